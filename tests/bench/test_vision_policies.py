"""`bench/vision_policies.py`: which runs a camera experiment trains, evaluates and compares, its flags, and its table
(the commands themselves are the CLI's, tested in tests/train/test_vision_bc.py)."""

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import vision_policies as vp  # noqa: E402


def _results(successes: int, n: int) -> dict:
    return {"cells": [{"n": n, "successes": successes, "modes": {"Successful placement": successes,
                                                                  "No-release truncation": n - successes}}],
            "provenance": {"seen_in_training": {"episodes": 0, "of": n}}, "mean_sr": successes / n,
            "inputs": "vision"}


def test_the_plan_two_seeds_a_blind_control_comparisons_and_both_learning_curves(tmp_path, monkeypatch):
    data = tmp_path / "data"
    (data / "meta").mkdir(parents=True)
    (data / "meta" / "info.json").write_text(json.dumps({"total_frames": 1000}))
    trained, evaluated, compared = [], [], []

    def train(steps, b, name, seed, *extra, until=None):
        trained.append((name, seed, until or b.steps, extra))
        (steps.out / name / "checkpoint").mkdir(parents=True, exist_ok=True)
        return steps.out / name / "checkpoint"

    monkeypatch.setattr(vp, "train", train)
    monkeypatch.setattr(vp, "evaluate", lambda steps, b, name, ck: evaluated.append(name) or _results(3, 4))
    overall = {"n": 4, "only_a": 2, "only_b": 0, "diff95": [-0.1, 0.8], "p_value": 0.5, "verdict": "underpowered"}
    monkeypatch.setattr(vp, "compare", lambda steps, name, a, b: compared.append(name) or {"overall": overall})
    budget = vp.Budget(dataset=str(data), seeds=(0, 1), steps=100, fractions=(0.5,), curve_steps=(50,),
                       privileged="priv/results.json")
    summary = vp.run(budget, tmp_path / "out")
    assert trained == [("camera_s0", 0, 50, ()), ("camera_s0", 0, 100, ()), ("camera_s1", 1, 100, ()),
                       ("blind_s0", 0, 100, ("--blind",)), ("camera_f0.5", 0, 100, ("--max-transitions", 500))]
    assert (tmp_path / "out" / "camera_s0_at50" / "checkpoint").is_dir()  # the step-50 checkpoint kept apart
    assert evaluated == ["eval_camera_s0_at50", "eval_camera_s0", "eval_camera_s1", "eval_blind_s0", "eval_camera_f0.5"]
    assert compared == ["compare_camera_s0_blind", "compare_camera_s1_blind", "compare_camera_privileged"]
    assert [(r["fraction"], r["steps"]) for r in summary["learning_curve"]] == [(0.5, 100), (1.0, 50), (1.0, 100)]
    assert json.loads((tmp_path / "out" / "vision.json").read_text())["rows"][2]["policy"] == "blind_s0"
    text = vp.table(summary)
    assert "| camera_s0 | 100 | 100% | 3/4 |" in text
    assert "camera_s0 vs blind_s0: 2 won by A only, 0 by B only of 4; difference -10.0 to 80.0 points" in text


def test_flags_parse_into_the_budget_and_bad_curves_are_refused():
    budget, out, png = vp.parse(["--dataset", "d", "--seeds", "0,1", "--steps", "1000", "--curve-steps", "250,500",
                                 "--fractions", "0.25", "--no-blind", "--out", "o", "--plot", "c.png"])
    assert (budget.seeds, budget.curve_steps, budget.fractions, budget.blind) == ((0, 1), (250, 500), (0.25,), False)
    assert (str(out), str(png)) == ("o", "c.png")
    with pytest.raises(SystemExit):
        vp.parse(["--dataset", "d", "--steps", "100", "--curve-steps", "200"])


def test_a_curve_from_evaluations_already_run_trains_nothing_and_plots_the_fractions(tmp_path):
    points = []
    for fraction, successes in ((0.25, 1), (0.5, 2), (1, 3)):
        folder = tmp_path / f"eval_{fraction}"
        folder.mkdir()
        (folder / "results.json").write_text(json.dumps({**_results(successes, 4), "label": f"f{fraction}"}))
        points += ["--curve-from", f"{fraction}={folder}"]
    (tmp_path / "more.json").write_text(json.dumps({**_results(4, 4), "label": "f1, other starts"}))
    points[-1] += f",{tmp_path / 'more.json'}"  # two sets of starts pooled into one point
    summary = vp.main(points + ["--steps", "600", "--eval-seed", "7", "--out", str(tmp_path / "out"),
                                "--plot", str(tmp_path / "curve.png")])
    assert [(r["fraction"], r["successes"], r["n"]) for r in summary["learning_curve"]] == [(0.25, 1, 4), (0.5, 2, 4),
                                                                                             (1.0, 7, 8)]
    assert json.loads((tmp_path / "out" / "curve.json").read_text())["budget"]["eval_seed"] == "7"
    assert (tmp_path / "curve.png").stat().st_size > 0
    with pytest.raises(SystemExit, match="no results"):
        vp.main(["--curve-from", f"0.5={tmp_path / 'missing'}", "--steps", "600", "--eval-seed", "7",
                 "--out", str(tmp_path / "out")])


def test_a_curve_over_training_steps_from_one_runs_checkpoints(tmp_path):
    points = []
    for steps, successes in ((1000, 0), (3000, 2), (6000, 3)):
        (tmp_path / f"at{steps}.json").write_text(json.dumps({**_results(successes, 4), "label": f"at{steps}"}))
        points += ["--curve-from", f"{steps}={tmp_path / f'at{steps}.json'}"]
    summary = vp.main(points + ["--over", "steps", "--steps", "6000", "--eval-seed", "7", "--out", str(tmp_path / "o"),
                                "--plot", str(tmp_path / "steps.png")])
    assert [(r["steps"], r["fraction"], r["successes"]) for r in summary["learning_curve"]] == [
        (1000, 1.0, 0), (3000, 1.0, 2), (6000, 1.0, 3)]
    assert (tmp_path / "steps.png").stat().st_size > 0
