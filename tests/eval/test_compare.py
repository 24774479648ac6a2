"""`aerobench compare`: paired tables, the exact McNemar p-value, Newcombe's interval, verdicts, refusals."""

import json
from pathlib import Path

import pytest

from aerobench.eval.compare import compare, compare_diagnostic, format_comparison, format_diagnostic, load_run
from aerobench.eval.results import summarize, write_results
from aerobench.eval.stats import mcnemar_sample_size, paired_difference_interval
from tests.cli_here import aerobench_here

ROOT = Path(__file__).resolve().parents[2]


def _record(index: int, outcome: str, policy: str, seed_base: int = 4200, skill: str = "pick",
            obj: str = "sugar_box") -> dict:
    return {"episode_index": index, "seed": seed_base * 1_000_003 + index, "setting": "TidyHouse", "skill": skill,
            "object": obj, "policy": policy, "outcome": outcome, "mode": "Successful pick" if outcome == "S" else "x",
            "cause": ""}


def _results(tmp_path: Path, name: str, outcomes: list[str], seed: int = 4200) -> Path:
    rows = [_record(i, o, name, seed) for i, o in enumerate(outcomes)]
    return write_results(tmp_path / f"{name}.json", summarize(rows, {"seed": seed}, label=name))


def _pair(both: int, only_a: int, only_b: int, neither: int) -> tuple[list[str], list[str]]:
    a = ["S"] * both + ["S"] * only_a + ["F"] * only_b + ["F"] * neither
    b = ["S"] * both + ["F"] * only_a + ["S"] * only_b + ["F"] * neither
    return a, b


def test_newcombe_interval_matches_the_published_example():
    # Newcombe (1998), paired example a=36, b=12, c=2, d=0 (n=50): method 10 gives 0.0569 to 0.3404
    lo, hi = paired_difference_interval(36, 12, 2, 0)
    assert (round(lo, 4), round(hi, 4)) == (0.0569, 0.3404)
    lo, hi = paired_difference_interval(5, 2, 2, 11)  # no discordant imbalance: symmetric about 0
    assert lo == pytest.approx(-hi) and lo < 0 < hi
    assert paired_difference_interval(20, 0, 0, 0) == pytest.approx((-0.1611, 0.1611), abs=1e-4)
    assert mcnemar_sample_size(0.2, 0.1) > mcnemar_sample_size(0.2, 0.2) > 0


def test_known_discordant_counts_give_the_known_p_value_interval_and_verdict(tmp_path):
    a, b = _pair(both=15, only_a=10, only_b=2, neither=3)
    cmp = compare(_results(tmp_path, "a", a), _results(tmp_path, "b", b))
    row = cmp["overall"]
    assert (row["n"], row["both"], row["only_a"], row["only_b"], row["neither"]) == (30, 15, 10, 2, 3)
    assert row["p_value"] == pytest.approx(158 / 4096)  # 2 * P(X <= 2), X ~ Bin(12, 1/2)
    assert row["diff95"] == pytest.approx([0.04135, 0.45970], abs=1e-5)
    assert row["verdict"] == "A better"
    assert cmp["cells"][0]["skill"] == "pick" and cmp["cells"][0]["n"] == 30
    swapped = compare(tmp_path / "b.json", tmp_path / "a.json")["overall"]
    assert swapped["verdict"] == "B better" and swapped["diff95"] == pytest.approx([-0.45970, -0.04135], abs=1e-5)
    assert "A better" in format_comparison(cmp)


def test_verdicts_say_no_difference_or_underpowered(tmp_path):
    a, b = _pair(both=190, only_a=2, only_b=2, neither=6)  # n = 200, tight interval around 0
    row = compare(_results(tmp_path, "a", a), _results(tmp_path, "b", b))["overall"]
    assert row["verdict"].startswith("no detectable difference at this n")
    a, b = _pair(both=10, only_a=3, only_b=2, neither=5)  # n = 20
    row = compare(_results(tmp_path, "c", a), _results(tmp_path, "d", b))["overall"]
    assert row["verdict"].startswith("underpowered: about ") and row["n_needed"] > 20


def test_holm_across_cells(tmp_path):
    """Three cells: A wins 10 of 10 discordant pairs in one (p = 2^-9), 6 of 6 in another (p = 2^-5), none differ in
    the third. Holm: 3 x 2^-9 < 0.05 differs; 2 x 2^-5 = 0.0625 does not, though its own p is below 0.05."""
    cells = {"sugar_box": _pair(both=5, only_a=10, only_b=0, neither=5), "bowl": _pair(both=10, only_a=6, only_b=0,
             neither=4), "cracker_box": _pair(both=10, only_a=0, only_b=0, neither=10)}
    paths = []
    for name, side in (("a", 0), ("b", 1)):
        rows = [_record(20 * k + i, o, name, obj=obj) for k, (obj, pair) in enumerate(cells.items())
                for i, o in enumerate(pair[side])]
        paths.append(write_results(tmp_path / f"{name}.json", summarize(rows, {"seed": 4200}, label=name)))
    cmp = compare(*paths)
    by_object = {row["object"]: row for row in cmp["cells"]}
    assert by_object["sugar_box"]["p_holm"] == pytest.approx(3 * 2**-9)
    assert by_object["bowl"]["p_value"] == pytest.approx(2**-5) and by_object["bowl"]["decision"] == "A better"
    assert by_object["bowl"]["p_holm"] == pytest.approx(2 * 2**-5) and by_object["cracker_box"]["p_holm"] == 1.0
    assert cmp["holm"] == {"cells": 3, "a_better": [["pick", "sugar_box"]], "b_better": []}
    assert "Holm over the 3 cells (family-wise alpha 0.05): A better in 1 (pick sugar_box), B better in none" \
        in format_comparison(cmp)


def test_init_failures_are_left_out_of_the_pairs(tmp_path):
    a, b = _pair(both=4, only_a=1, only_b=0, neither=1)
    b[0] = "I"  # B's env rejected the first start
    cmp = compare(_results(tmp_path, "a", a), _results(tmp_path, "b", b))
    assert cmp["excluded_init_failures"] == 1 and cmp["overall"]["n"] == 5


def test_different_starts_are_refused_in_one_line(tmp_path):
    _results(tmp_path, "a", ["S"] * 4)
    _results(tmp_path, "b", ["S"] * 4, seed=4201)
    _results(tmp_path, "c", ["S"] * 5)
    with pytest.raises(ValueError, match=r"do not share their starts \(--seed 4200 and 4201\)"):
        compare(tmp_path / "a.json", tmp_path / "b.json")
    with pytest.raises(ValueError, match="different episode plans"):
        compare(tmp_path / "a.json", tmp_path / "c.json")
    r = aerobench_here("compare", str(tmp_path / "a.json"), str(tmp_path / "b.json"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "do not share their starts" in r.stderr


def test_old_results_are_paired_through_the_records_beside_them(tmp_path):
    path = _results(tmp_path, "a", ["S", "F", "S"])
    data = json.loads(path.read_text())
    for cell in data["cells"]:
        del cell["episodes"]
    data["provenance"]["records"] = "records.jsonl"
    path.write_text(json.dumps(data))
    (tmp_path / "records.jsonl").write_text("".join(json.dumps(_record(i, o, "a")) + "\n"
                                                    for i, o in enumerate(["S", "F", "S"])))
    assert {i: e[3] for i, e in load_run(path).episodes.items()} == {0: "S", 1: "F", 2: "S"}
    (tmp_path / "records.jsonl").unlink()
    with pytest.raises(ValueError, match="lists no per-episode outcomes"):
        load_run(path)


def test_compare_two_committed_results_prints_a_verdict():
    results = ROOT / "leaderboards" / "results"
    r = aerobench_here("compare", str(results / "PackageDelivery_bc_skills.json"),
                       str(results / "PackageDelivery_expert_skills.json"))
    assert r.returncode == 0, r.stderr
    overall = next(line for line in r.stdout.splitlines() if line.startswith("all "))
    assert " 40 " in overall and ("underpowered" in overall or "no detectable difference" in overall
                                  or "better" in overall)


def _eval_folder(folder: Path, name: str, distances: list[float | None]) -> Path:
    """An eval folder whose records carry `min_tcp_to_grasp_point_m` (None: an episode rejected at initialization)."""
    folder.mkdir()
    rows = [_record(i, "I" if d is None else "F", name) | {"diagnostics": {"min_tcp_to_grasp_point_m": d}}
            for i, d in enumerate(distances)]
    (folder / "records.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    write_results(folder / "results.json", summarize(rows, {"seed": 4200, "records": "records.jsonl"}, label=name))
    return folder


def test_a_record_diagnostic_is_compared_start_by_start(tmp_path):
    near = _eval_folder(tmp_path / "near", "near", [0.10, 0.20, 0.05, 0.30, 0.12, 0.08, 0.15, None])
    far = _eval_folder(tmp_path / "far", "far", [0.40, 0.50, 0.45, 0.35, 0.60, 0.70, 0.55, 0.20])
    cmp = compare_diagnostic(near, far, "min_tcp_to_grasp_point_m")
    assert (cmp["n"], cmp["a_lower"], cmp["a_higher"]) == (7, 7, 0)  # the rejected start is left out
    assert cmp["a"]["median"] == pytest.approx(0.12) and cmp["b"]["median"] == pytest.approx(0.50)
    assert cmp["p_value"] == pytest.approx(2 / 2**7)  # exact: every difference the same sign, n = 7
    assert "A lower on 7 of 7" in format_diagnostic(cmp)
    assert compare_diagnostic(near, near, "min_tcp_to_grasp_point_m")["p_value"] == 1.0
    with pytest.raises(ValueError, match="no record diagnostic 'speed'"):
        compare_diagnostic(near, far, "speed")
    r = aerobench_here("compare", str(near), str(far), "--diagnostic", "min_tcp_to_grasp_point_m")
    assert r.returncode == 0 and "A lower on 7 of 7" in r.stdout, r.stderr
