"""Real-time evaluation (`rollout.realtime`): which command the env receives at each step under a known latency, the
hold commands, latency 0 as today's evaluation, and what records and results files say about it."""

import json
import types

import numpy as np
import pytest
import torch

from aerobench.envs.platforms import PLATFORMS
from aerobench.rollout.episode import EpisodeList
from aerobench.rollout.realtime import RealtimePolicy, RealtimeSpec, latency_steps, start_command
from aerobench.rollout.runner import RolloutRunner, RolloutSpec
from tests.cli_here import aerobench_here

GRIPPER = PLATFORMS["gripper"]


def fake_base(starts_held: bool = False, platform=GRIPPER):
    return types.SimpleNamespace(num_envs=1, platform=platform, device="cpu", control_freq=20,
                                 starts_held=torch.tensor([starts_held]))


class StepPolicy:
    """Acts with the number of the step it observed (the runner's observation here is that number), 10 + step, in
    every column but the gripper's; with `chunk` > 1 it answers chunks [10 + step, 10.1 + step, ...]."""

    def __init__(self, chunk: int = 1, clock=None, compute_ms: float = 0.0):
        self.chunked, self.n, self.clock, self.compute_ms, self.calls = chunk > 1, chunk, clock, compute_ms, []

    def reset(self, env_idx):
        pass

    def _think(self, t):
        self.calls.append(t)
        if self.clock is not None:
            self.clock.now += self.compute_ms / 1000.0

    def act(self, t):
        self._think(t)
        return torch.full((1, 5), 10.0 + t)

    def act_chunk(self, t):
        self._think(t)
        return torch.stack([torch.full((1, 5), 10.0 + t + 0.1 * i) for i in range(self.n)], dim=1)


def executed(spec: RealtimeSpec, steps: int = 10, chunk: int = 1, starts_held: bool = False, **policy_kwargs):
    """The flight command u_x and the gripper command the env receives at each step, and the wrapper."""
    policy = StepPolicy(chunk, **policy_kwargs)
    clock = policy_kwargs.get("clock")
    wrapper = RealtimePolicy(policy, fake_base(starts_held), spec, **({"clock": (lambda: clock.now)} if clock else {}))
    wrapper.reset(torch.arange(1))
    commands = [wrapper.act(t)[0] for t in range(steps)]
    return [round(float(c[0]), 1) for c in commands], [round(float(c[-1]), 1) for c in commands], wrapper


def test_latency_is_whole_control_steps_rounded_up():
    assert [latency_steps(ms, 0.05) for ms in (0, 0.001, 49.9, 50, 50.5, 100, 120, 150, 151)] == [0, 1, 1, 1, 2, 2, 3, 3, 4]


def test_latency_zero_asks_every_step_and_acts_at_once():
    flight, _, wrapper = executed(RealtimeSpec(0.0))
    assert flight == [10.0 + t for t in range(10)]
    assert wrapper.summary(10)["held_steps"] == 0 and wrapper.summary(10)["command_age_steps_max"] == 0


H = 0.0  # the start command's u_x: hover


@pytest.mark.parametrize("schedule, hold, expected", [
    # 120 ms = 3 steps: an answer to the observation of step t applies at t + 3
    ("sync", "last", [H, H, H, 10, 10, 10, 10, 14, 14, 14, 14, 18]),  # asked again once its action ran (steps 4, 8)
    ("sync", "hover", [H, H, H, 10, H, H, H, 14, H, H, H, 18]),
    ("async", "last", [H, H, H, 10, 10, 10, 13, 13, 13, 16, 16, 16]),  # asked again as soon as it answers (3, 6, 9)
    ("async", "hover", [H, H, H, 10, H, H, 13, H, H, 16, H, H]),
])
def test_which_command_the_env_receives_at_each_step(schedule, hold, expected):
    flight, _, wrapper = executed(RealtimeSpec(120.0, hold, schedule), steps=12)
    assert flight == expected
    summary = wrapper.summary(12)
    assert summary["latency_steps_max"] == 3 and summary["latency_ms_mean"] == 120.0
    assert summary["held_steps"] == 9  # a fresh answer at 3 of the 12 steps, the hold command at the others
    assert summary["requests"] == (3 if schedule == "sync" else 4)


def test_held_steps_and_command_ages_per_step():
    flight, _, wrapper = executed(RealtimeSpec(120.0, "last", "sync"), steps=8)
    trace = wrapper.trace(8)
    assert trace["realtime_held"].tolist() == [True, True, True, False, True, True, True, False]
    # the command run at each step was computed from the observation this many steps back (-1: none yet)
    assert trace["realtime_command_age_steps"].tolist() == [-1, -1, -1, 3, 4, 5, 6, 3]
    assert np.isfinite(trace["realtime_request_ms"]).tolist() == [True, False, False, False, True, False, False, False]
    assert wrapper.summary(8)["held_steps"] == 6 and wrapper.summary(8)["requests"] == 2


@pytest.mark.parametrize("schedule, expected", [
    # a chunk of 4 answered 100 ms (2 steps) late; it plays from its first action
    ("sync", [H, H, 10, 10.1, 10.2, 10.3, 10.3, 10.3, 16, 16.1, 16.2, 16.3]),  # asked when it ran out (step 6)
    ("async", [H, H, 10, 10.1, 10.2, 10.3, 14, 14.1, 14.2, 14.3, 18, 18.1]),  # asked 2 steps before (4, 8): no gap
])
def test_chunks_play_as_on_a_robot(schedule, expected):
    flight, _, _ = executed(RealtimeSpec(100.0, "last", schedule), steps=12, chunk=4)
    assert flight == expected


def test_a_chunk_at_latency_zero_is_asked_once_per_chunk():
    flight, _, wrapper = executed(RealtimeSpec(0.0), steps=8, chunk=4)
    assert flight == [10, 10.1, 10.2, 10.3, 14, 14.1, 14.2, 14.3]
    assert wrapper.policy.calls == [0, 4]


def test_measured_latency_is_the_policys_own_time():
    clock = types.SimpleNamespace(now=0.0)
    flight, _, wrapper = executed(RealtimeSpec(None), steps=6, clock=clock, compute_ms=70.0)  # 70 ms: 2 steps
    assert flight == [H, H, 10, 10, 10, 13]
    summary = wrapper.summary(6)
    assert summary["latency_ms"] == "measured" and summary["latency_steps_max"] == 2
    assert summary["latency_ms_max"] == pytest.approx(70.0)


def test_before_the_first_answer_the_drone_hovers_holding_what_it_holds():
    _, gripper, _ = executed(RealtimeSpec(100.0), steps=3)
    assert gripper[:2] == [1.0, 1.0]  # open, as the reset leaves the fingers
    _, gripper, _ = executed(RealtimeSpec(100.0), steps=3, starts_held=True)
    assert gripper[:2] == [-1.0, -1.0]  # a Place episode starts holding its object: closed, not dropped
    assert start_command(fake_base())[0, :4].tolist() == [0.0, 0.0, 0.0, 0.0]


def test_hover_keeps_the_gripper_command():
    flight, gripper, _ = executed(RealtimeSpec(120.0, "hover", "sync"), steps=6)
    assert flight[3:] == [10, H, H] and gripper[3:] == [10, 10, 10]


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="--hold takes last or hover"):
        RealtimeSpec(10.0, hold="freeze")
    with pytest.raises(ValueError, match="--inference-latency-ms must be a finite number >= 0"):
        RealtimeSpec(-5.0)
    with pytest.raises(ValueError, match="--schedule takes sync or async"):
        RealtimeSpec(10.0, schedule="later")


# ----------------------------------------------------------------------------------------------------------------------
def _expert_picks(realtime: RealtimeSpec | None) -> list:
    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=2, objects=("master_chef_can",), policy="expert",
                       record_cameras=False, realtime=realtime)
    sink = EpisodeList()
    RolloutRunner(spec, sink).run()
    return sink.episodes


def test_latency_zero_reproduces_todays_evaluation_and_latency_changes_it():
    today, zero, late = _expert_picks(None), _expert_picks(RealtimeSpec(0.0)), _expert_picks(RealtimeSpec(150.0))
    assert [e.record.outcome for e in today] == ["S", "S"]  # full expert Pick episodes, not truncated ones
    for a, b in zip(today, zero):
        assert a.record.to_dict() == b.record.to_dict()
        np.testing.assert_array_equal(a.frames["action"], b.frames["action"])
        assert b.extra["realtime"]["held_steps"] == 0 and b.extra["realtime"]["command_age_steps_max"] == 0
    for a, c in zip(today, late):  # 3 steps late: the same starts, other commands, the latency in the record
        assert c.extra["realtime"]["latency_steps_max"] == 3 and c.extra["realtime"]["held_steps"] >= 3
        assert not np.array_equal(a.frames["action"][:20], c.frames["action"][:20])
        assert c.signals["realtime_command_age_steps"][:4].tolist() == [-1, -1, -1, 3]


def test_eval_realtime_records_its_settings(tmp_path):
    out = tmp_path / "eval"
    proc = aerobench_here("eval", "--policy", "expert", "--setting", "TidyHouse", "--skills", "pick", "--objects",
                          "master_chef_can", "--episodes-per-object", "1", "--max-steps", "12", "--realtime",
                          "--inference-latency-ms", "100", "--hold", "hover", "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-2000:]
    results = json.loads((out / "results.json").read_text())
    assert results["provenance"]["realtime"] == {"latency_ms": 100.0, "hold": "hover", "schedule": "sync"}
    assert json.loads((out / "run.json").read_text())["realtime"]["latency_ms"] == 100.0  # part of the run's identity
    (record,) = [json.loads(line) for line in (out / "records.jsonl").read_text().splitlines()]
    timing = record["extra"]["realtime"]
    assert (timing["latency_steps_max"], timing["requests"], timing["hold"]) == (2, 4, "hover")  # asked at 0, 3, 6, 9
    assert timing["held_steps"] == 8 and record["steps"] == 12


def test_realtime_options_need_realtime(tmp_path):
    proc = aerobench_here("eval", "--policy", "expert", "--setting", "TidyHouse", "--skills", "pick",
                          "--inference-latency-ms", "100", "--out", str(tmp_path / "x"))
    assert proc.returncode == 2 and proc.stderr.strip().splitlines() == [
        "aerobench eval: error: --inference-latency-ms, --hold and --schedule set up --realtime: add --realtime"]
    assert not (tmp_path / "x").exists()
