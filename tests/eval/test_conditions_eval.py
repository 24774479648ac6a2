"""`aerobench conditions`, and `eval` / `generate --condition`: the names pass through to the env, results record
each condition's name, version and parameters, the starts are the nominal run's, and a bad name is one line."""

from __future__ import annotations

import json

from aerobench.envs.conditions import CONDITIONS
from aerobench.eval.row_facts import group_key
from aerobench.rollout.runner import RolloutSpec, plan_episodes
from tests.cli_here import aerobench_here

TINY = ["--policy", "expert", "--setting", "TidyHouse", "--skills", "pick", "--objects", "bowl",
        "--episodes-per-object", "1", "--max-steps", "3"]


def test_conditions_lists_one_line_per_condition():
    done = aerobench_here("conditions")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.strip().splitlines()
    assert [line.split()[0] for line in lines] == list(CONDITIONS)
    assert all(f" v{CONDITIONS[line.split()[0]].version} " in line and "source: " in line for line in lines)


def test_an_unknown_condition_is_one_line():
    for command in (["eval", *TINY, "--out", "unused"], ["generate", "--setting", "TidyHouse", "--skills", "pick",
                                                         "--episodes", "1", "--out", "unused"]):
        done = aerobench_here(*command, "--condition", "wind_gusty_3ms,hurricane")
        assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
        assert "unknown condition 'hurricane'; valid conditions: wind_steady_2ms" in done.stderr
    done = aerobench_here("eval", *TINY, "--condition", "motor_lag,motor_lag_slow", "--out", "unused")
    assert done.returncode == 2 and "both set the motor_lag model" in done.stderr


def test_rollout_spec_names_its_condition_only_when_there_is_one():
    nominal = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=2)
    windy = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=2, condition="wind_gusty_3ms,motor_lag")
    assert "condition" not in nominal.as_dict()  # runs recorded before conditions stay resumable
    assert windy.as_dict()["condition"] == ["wind_gusty_3ms", "motor_lag"]
    assert plan_episodes(windy) == plan_episodes(nominal)  # the same starts


def test_eval_under_a_condition_records_it(tmp_path):
    done = aerobench_here("eval", *TINY, "--condition", "wind_gusty_3ms,motor_lag", "--out", str(tmp_path / "windy"))
    assert done.returncode == 0, done.stderr
    results = json.loads((tmp_path / "windy" / "results.json").read_text())
    recorded = results["provenance"]["conditions"]
    assert [c["name"] for c in recorded] == ["wind_gusty_3ms", "motor_lag"]
    assert recorded[0]["version"] == 1 and recorded[0]["parameters"]["wind"]["mean_speed_mps"] == 3.0
    assert recorded[1]["parameters"]["motor_lag"]["time_constant_up_s"] == 0.0125 and recorded[1]["source"]
    assert json.loads((tmp_path / "windy" / "run.json").read_text())["condition"] == ["wind_gusty_3ms", "motor_lag"]
    seeds = [e[1] for c in results["cells"] for e in c["episodes"]]
    nominal = RolloutSpec(setting="TidyHouse", skills=("pick",), objects=("bowl",), episodes=1)
    assert seeds == [p.seed for p in plan_episodes(nominal)]
    key = group_key(results)  # never ranked with nominal rows: the condition is part of the group
    assert key.condition == "wind_gusty_3ms v1, motor_lag v1" and "condition wind_gusty_3ms v1" in key.title()
    summary = tmp_path / "summary.json"  # records summarized later keep the run's condition names (run.json)
    assert aerobench_here("summarize", str(tmp_path / "windy"), "--out", str(summary)).returncode == 0
    assert group_key(json.loads(summary.read_text())).condition == "wind_gusty_3ms, motor_lag"
