"""The spec's PrepareGroceries table (Downstream Policy Benchmarking) as counts, for the leaderboard tests."""

OBJECTS = ("master_chef_can", "sugar_box", "tomato_soup_can", "tuna_fish_can", "pudding_box", "gelatin_box",
           "potted_meat_can", "bowl")

# policy -> skill -> (episodes per cell, success % per object in OBJECTS order)
SPEC_TABLE = {
    "ACT": {"pick": (50, (2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 10.0, 18.0)),
            "place": (50, (24.0, 98.0, 28.0, 82.0, 46.0, 48.0, 56.0, 60.0))},
    "DP": {"pick": (50, (4.0, 2.0, 6.0, 4.0, 2.0, 2.0, 2.0, 6.0)),
           "place": (50, (50.0, 90.0, 50.0, 78.0, 82.0, 80.0, 32.0, 52.0))},
    "PI0": {"pick": (30, (6.7, 6.7, 10.0, 20.0, 13.3, 13.3, 13.3, 6.7)),
            "place": (50, (80.0, 82.0, 52.0, 88.0, 52.0, 68.0, 86.0, 24.0))},
    "PI05": {"pick": (50, (8.0, 6.0, 6.0, 12.0, 14.0, 16.0, 16.0, 14.0)),
             "place": (50, (60.0, 88.0, 64.0, 92.0, 96.0, 96.0, 78.0, 48.0))},
}
SPEC_MEAN_SR = {"ACT": 29.5, "DP": 33.9, "PI0": 38.9, "PI05": 44.6}


def spec_records(policy: str) -> list[dict]:
    """Episode-record rows reproducing the spec's counts for one policy."""
    rows, index = [], 0
    for skill, (n, percents) in SPEC_TABLE[policy].items():
        for obj, pct in zip(OBJECTS, percents, strict=True):
            k = round(pct * n / 100)
            for j in range(n):
                ok = j < k
                rows.append({
                    "episode_index": index, "setting": "PrepareGroceries", "policy": policy.lower(), "skill": skill,
                    "object": obj, "outcome": "S" if ok else "F", "cause": "" if ok else "collision",
                    "mode": ("Successful grasp handoff" if skill == "pick" else "Successful placement") if ok
                    else "Collision failure", "segments": [],
                })
                index += 1
    return rows
