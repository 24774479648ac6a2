"""`aerobench publish`: a row's results and the videos of its own starts into a leaderboard folder."""

from pathlib import Path

import pytest

from aerobench.eval.leaderboard_folder import build_leaderboard
from aerobench.eval.publish import publish
from aerobench.eval.results import load_results, summarize, write_results
from tests.cli_here import aerobench_here


def _eval_dir(folder: Path, outcomes: list[str], videos: tuple[int, ...] = (), seed: int = 4200,
              policy: str = "expert") -> Path:
    """An eval folder as `aerobench eval` leaves it: results.json and `videos/episode_<index>.mp4`."""
    rows = [{"episode_index": i, "seed": seed * 1_000_003 + i, "setting": "TidyHouse", "skill": "pick",
             "object": "sugar_box", "policy": policy, "outcome": o, "mode": "Successful pick" if o == "S" else "x",
             "cause": ""} for i, o in enumerate(outcomes)]
    results = summarize(rows, {"seed": seed, "policy": policy}, label=policy)
    if videos:
        (folder / "videos").mkdir(parents=True)
        for i in videos:
            (folder / "videos" / f"episode_{i:06d}.mp4").write_bytes(b"mp4 of episode %d" % i)
        results["videos"] = [f"videos/episode_{i:06d}.mp4" for i in videos]
    write_results(folder / "results.json", results)
    return folder


def test_a_row_gets_the_videos_of_a_small_eval_of_its_own_starts(tmp_path):
    row = _eval_dir(tmp_path / "row", ["S", "F", "S", "S", "S", "S"])  # a long state-only run, no videos
    small = _eval_dir(tmp_path / "small", ["S", "F"], videos=(0, 1))  # its first two starts again, with --video 2
    dest = tmp_path / "boards" / "results" / "TidyHouse_expert.json"
    published = publish(row, dest, videos_from=small)
    assert published["videos"] == ["TidyHouse_expert_videos/episode_000000.mp4", "TidyHouse_expert_videos/episode_000001.mp4"]
    assert (dest.parent / "TidyHouse_expert_videos" / "episode_000001.mp4").read_bytes() == b"mp4 of episode 1"
    assert load_results(dest)["cells"] == load_results(row / "results.json")["cells"]  # the row's own numbers
    build_leaderboard([dest], tmp_path / "boards")
    page = (tmp_path / "boards" / "index.html").read_text()
    assert 'href="results/TidyHouse_expert_videos/episode_000000.mp4"' in page  # linked from the page's folder
    publish(dest, dest)  # a published row published again in place keeps its videos
    assert (dest.parent / "TidyHouse_expert_videos" / "episode_000001.mp4").read_bytes() == b"mp4 of episode 1"
    assert load_results(dest)["videos"] == published["videos"]
    # publishing again without videos removes the old ones: nothing stale is left beside the row
    publish(row, dest)
    assert "videos" not in load_results(dest) and not (dest.parent / "TidyHouse_expert_videos").exists()


@pytest.mark.parametrize("case, match", [
    ("other seed", "another run \\(--seed 4201"),
    ("other policy", "another run \\(policy 'bc'"),
    ("other outcome", "is not the row's episode 1"),
])
def test_videos_of_other_starts_or_another_policy_are_refused(tmp_path, case, match):
    row = _eval_dir(tmp_path / "row", ["S", "F", "S"])
    small = _eval_dir(tmp_path / "small", ["S", "S"] if case == "other outcome" else ["S", "F"], videos=(0, 1),
                      seed=4201 if case == "other seed" else 4200, policy="bc" if case == "other policy" else "expert")
    with pytest.raises(ValueError, match=match):
        publish(row, tmp_path / "out.json", videos_from=small)
    assert not (tmp_path / "out.json").exists()


def test_the_cli_publishes_and_errors_in_one_line(tmp_path):
    row = _eval_dir(tmp_path / "row", ["S", "S"], videos=(0,))
    r = aerobench_here("publish", str(row), "--to", str(tmp_path / "x.json"))
    assert r.returncode == 0 and "1 videos" in r.stdout, r.stderr
    r = aerobench_here("publish", str(row), "--to", str(tmp_path / "x.txt"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "must name a .json" in r.stderr
