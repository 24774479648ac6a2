"""Today's physics stays what it is: the airframe's per-step joint states of short expert episodes, recorded before
evaluation conditions existed (`nominal_physics.json`), against fresh runs with no condition and with an empty one.

Committed leaderboard rows were flown with this physics, so a change here changes what those rows mean. The default
(no condition) takes no new code path at all: the body controller runs the same fused step (checked below), the
observation and the task state are computed as before. Recorded with the eager physics step (as the tests run,
tests/conftest.py); the comparison allows 1e-5 (m, rad, m/s, rad/s) so that a CPU whose vector math rounds a last bit
differently still passes, while any change of the flight physics moves a state by far more within a few steps.
Regenerate only when the physics is meant to change: `python tests/envs/test_nominal_physics.py --write`.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401
from aerobench.rollout.runner import SEED_STRIDE

FIXTURE = Path(__file__).with_name("nominal_physics.json")
TOLERANCE = 1e-5
STEPS = 40

# (env id, env kwargs, object, episode seed): both platforms, so the arm's servo torques are in the recorded efforts
CASES = [
    ("AeroPick-v1", {"setting": "TidyHouse"}, "bowl", 20 * SEED_STRIDE + 3),
    ("AeroPick-v1", {"setting": "PackageDelivery", "platform": "arm"}, "package", 11),
]


def case_key(env_id: str, kwargs: dict, obj: str, seed: int) -> str:
    return f"{env_id}/{kwargs.get('setting')}/{kwargs.get('platform', 'default')}/{obj}/{seed}"


def run_case(env_id: str, kwargs: dict, obj: str, seed: int, steps: int = STEPS, **extra) -> list[list[float]]:
    """The expert flies `steps` control steps; per step the virtual joints' positions and velocities (12 floats)."""
    from aerobench.policies import make_policy

    env = gym.make(env_id, obs_mode="state_dict", **kwargs, **extra)
    try:
        obs, _ = env.reset(seed=seed, options={"reconfigure": True, "objects": [obj]})
        base = env.unwrapped
        policy = make_policy("expert", base)
        policy.reset(torch.arange(base.num_envs))
        rows = []
        for _ in range(steps):
            obs, *_ = env.step(policy.act(obs))
            q, qd = base.agent.joint_state()
            rows.append([float(v) for v in torch.cat([q[0, :6], qd[0, :6]])])
        return rows
    finally:
        env.close()


def largest_difference(a: list[list[float]], b: list[list[float]]) -> float:
    return max(abs(x - y) for ra, rb in zip(a, b, strict=True) for x, y in zip(ra, rb, strict=True))


@pytest.mark.parametrize("case", CASES, ids=[case_key(*c) for c in CASES])
def test_no_condition_flies_the_recorded_physics(case):
    recorded = json.loads(FIXTURE.read_text())[case_key(*case)]
    assert largest_difference(recorded, run_case(*case)) <= TOLERANCE


def test_an_empty_condition_is_no_condition():
    """`condition=()` (what the rollout passes when none is named) is the default, bit for bit, and the body
    controller keeps the fused step: no conditioned physics is installed."""
    case = CASES[0]
    recorded = json.loads(FIXTURE.read_text())[case_key(*case)]
    assert largest_difference(recorded, run_case(*case, condition=())) <= TOLERANCE
    env = gym.make(case[0], obs_mode="state_dict", condition=(), **case[1])
    try:
        env.reset(seed=case[3], options={"reconfigure": True, "objects": [case[2]]})
        env.step(torch.zeros(env.action_space.shape))
        controller = env.unwrapped.agent.body_controller
        assert env.unwrapped.condition is None and env.unwrapped.condition_runtime is None
        assert controller.conditioned is None
        assert controller._efforts_loop is not None  # the lean fused step ran (the 240 Hz loop of before)
    finally:
        env.close()


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: python tests/envs/test_nominal_physics.py --write   (rewrites the recorded physics)")
    os.environ.setdefault("AEROBENCH_COMPILE", "0")  # as the tests run (tests/conftest.py)
    out = {case_key(*case): run_case(*case) for case in CASES}
    FIXTURE.write_text("{\n" + ",\n".join(f"  {json.dumps(k)}: [\n" + ",\n".join(f"    {json.dumps(r)}" for r in v)
                                          + "\n  ]" for k, v in out.items()) + "\n}\n")
    print(f"wrote {len(out)} trajectories of {STEPS} steps to {FIXTURE}")
