"""`bench/dagger.py`: the round loop's bookkeeping (held-out seeds, steps that run once and resume, the table), and
one smoke-sized DAgger run end to end through the CLI."""

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import dagger  # noqa: E402


def test_evaluation_seeds_may_not_be_a_demonstration_or_round_seed():
    with pytest.raises(ValueError, match="held out"):
        dagger.Budget(rounds=3, round_seed=700, eval_seed=702)
    with pytest.raises(ValueError, match="held out"):
        dagger.Budget(demo_seed=4250)
    assert dagger.Budget(rounds=3, round_seed=700, eval_seed=703).rounds == 3


def test_full_sets_the_documented_run_and_flags_override_it():
    budget, out = dagger.parse(["--full", "--skill", "close", "--rounds", "2", "--out", "somewhere"])
    assert (budget.skill, budget.rounds, budget.demos, budget.episodes_per_round) == ("close", 2, 240, 200)
    assert (budget.bc_steps, budget.final_per_object, str(out)) == (20_000, 60, "somewhere")
    assert dagger.parse([])[0] == dagger.Budget()


def test_a_step_runs_its_commands_once_and_a_failed_one_is_not_marked_done(tmp_path, monkeypatch):
    ran = []
    monkeypatch.setattr(dagger.Steps, "_processes", staticmethod(lambda cmds, logs: [ran.append(c) or 0 for c in cmds]))
    steps = dagger.Steps(tmp_path, "dagger")
    steps.run("shards", ["generate", "--shard", "0/2"], ["generate", "--shard", "1/2"])
    steps.run("shards", ["generate", "--shard", "0/2"], ["generate", "--shard", "1/2"])  # done: not run again
    assert ran == [["generate", "--shard", "0/2"], ["generate", "--shard", "1/2"]]
    assert (tmp_path / "shards.1.log").read_text() == "$ aerobench generate --shard 1/2\n"
    # one command runs in this process, through the CLI: a failure names its log and leaves no marker
    with pytest.raises(SystemExit, match="step info failed; see .*info.log"):
        steps.run("info", ["dataset", "info", str(tmp_path / "missing")])
    assert "no dataset folder at" in (tmp_path / "info.log").read_text()
    assert not (tmp_path / "done" / "info").exists() and (tmp_path / "done" / "shards").exists()


def _results(outcomes: list[str], modes: dict, seen: int) -> dict:
    return {"cells": [{"n": len(outcomes), "successes": outcomes.count("S"), "modes": modes}],
            "provenance": {"seen_in_training": {"episodes": seen, "of": len(outcomes)}}}


def test_a_row_pools_the_cells_and_lists_only_failure_modes(tmp_path):
    data = tmp_path / "j1"
    (data / "meta").mkdir(parents=True)
    (data / "meta" / "info.json").write_text(json.dumps({"total_episodes": 7, "total_frames": 1234}))
    results = _results(["S", "F", "T", "T"], {"Successful opening": 1, "No-pinch truncation": 2, "Slip failure": 1}, 0)
    row = dagger.summary_row("bc1", data, results, 4200)
    assert (row["episodes"], row["frames"], row["successes"], row["n"], row["seen_in_training"]) == (7, 1234, 1, 4, 0)
    assert row["failure_modes"] == {"No-pinch truncation": 2, "Slip failure": 1}
    assert 0 < row["wilson95"][0] < 0.25 < row["wilson95"][1] < 1
    text = dagger.table({"rounds": [row], "final": None})
    assert "| bc1 | 7 | 1,234 | 1/4 (4200) | 0 | No-pinch truncation 2, Slip failure 1 |" in text


def test_a_smoke_sized_dagger_run_trains_on_expert_labels_of_the_policys_own_flights(tmp_path):
    out = tmp_path / "run"
    argv = ["--setting", "PrepareGroceries", "--skill", "open", "--demos", "2", "--action-noise", "0",
            "--episodes-per-round", "1", "--bc-steps", "20", "--eval-per-object", "1", "--out", str(out)]
    summary = dagger.main(argv)
    first, second = summary["rounds"]
    assert first["policy"] == "bc0" and second["policy"] == "bc1"
    assert second["episodes"] == first["episodes"] + 1  # the flown episode joined whatever its outcome
    assert second["frames"] > first["frames"]
    assert all(row["seen_in_training"] == 0 for row in summary["rounds"])
    records = [json.loads(line) for line in (out / "r1" / ".aerobench" / "records.jsonl").read_text().splitlines()]
    assert [r["extra"]["labeler"] for r in records] == ["expert"]
    assert json.loads((out / "bc1" / "checkpoint" / "config.json").read_text())["data"]["episodes"] == 3
    marks = sorted(p.name for p in (out / "done").iterdir())
    assert marks == sorted(["demos", "demos.merge", "bc0", "eval0", "r1", "r1.merge", "j1", "bc1", "eval1"])
    again = dagger.main(argv)  # everything is done: the same table, nothing rerun
    assert again["rounds"] == summary["rounds"]


def test_a_run_continued_with_more_rounds_evaluates_its_new_last_policy_on_the_final_starts(tmp_path, monkeypatch):
    """The final evaluation's step is named after its policy: `--rounds 3` then `--rounds 5` on one folder evaluates
    bc5 on the final starts (its step was once named `final` for any policy, and a longer run reported bc3's)."""
    evaluated = []
    monkeypatch.setattr(dagger, "generate", lambda steps, b, name, *a: tmp_path / name)
    monkeypatch.setattr(dagger, "train", lambda steps, b, name, *a: tmp_path / name / "checkpoint")
    monkeypatch.setattr(dagger, "dataset_size", lambda folder: (1, 1))
    monkeypatch.setattr(dagger, "evaluate", lambda steps, b, name, checkpoint, *a: evaluated.append(
        (name, checkpoint.parent.name)) or {})
    monkeypatch.setattr(dagger, "summary_row", lambda name, data, results, seed: {"policy": name, "data": str(data)})
    monkeypatch.setattr(dagger.Steps, "run", lambda self, name, *commands: None)
    for rounds in (1, 2):
        summary = dagger.run(dagger.Budget(rounds=rounds, final_per_object=1), tmp_path)
        assert summary["final"]["policy"] == f"bc{rounds}" and evaluated[-1] == (f"final_bc{rounds}", f"bc{rounds}")
