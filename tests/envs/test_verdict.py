"""A control step's outcome (`checks.verdict`): the first failure latched in priority order, success only where
none, compiled as the eager function."""

from functools import partial

import gymnasium as gym
import pytest
import torch
from mani_skill.envs.sapien_env import BaseEnv

import aerobench.envs  # noqa: F401
from aerobench.envs.checks import FailureCause, verdict
from tests.envs.kernel_checks import assert_compiled_is_eager

pytestmark = [pytest.mark.usefixtures("aot_cache"), pytest.mark.xdist_group("aot_packages")]  # packages built here go to this run's cache

CAUSES = (int(FailureCause.COLLISION), int(FailureCause.OBJECT_DROP), int(FailureCause.TILT), int(FailureCause.LOW))


def _flags(*rows: tuple[bool, bool, bool, bool]) -> list[torch.Tensor]:
    """One `(N,)` flag per cause from per-env rows."""
    return [torch.tensor(column) for column in zip(*rows)]


def test_the_first_failure_is_latched_in_priority_order():
    current = torch.tensor([0, 0, 0, int(FailureCause.LOW), 0])
    success = torch.tensor([True, True, False, True, True])
    flags = _flags(
        (False, False, False, False),  # nothing: success stands
        (False, True, True, False),  # two causes at once: the first in priority order
        (True, False, False, True),
        (True, False, False, False),  # failed before: its first cause stays
        (False, False, False, True),
    )
    cause, fail, ok, reward = verdict(current, success, *flags, causes=CAUSES)
    assert cause.tolist() == [0, int(FailureCause.OBJECT_DROP), int(FailureCause.COLLISION), int(FailureCause.LOW),
                              int(FailureCause.LOW)]
    assert fail.tolist() == [False, True, True, True, True]
    assert ok.tolist() == [True, False, False, False, False]
    assert reward.tolist() == [1.0, -1.0, -1.0, -1.0, -1.0]  # ManiSkill's sparse reward


def test_the_compiled_verdict_is_the_eager_one(aot_cache):
    generator = torch.Generator().manual_seed(0)
    n = 64
    current = torch.where(torch.rand(n, generator=generator) < 0.3, torch.randint(1, 12, (n,), generator=generator), 0)
    success = torch.rand(n, generator=generator) < 0.5
    flags = [torch.rand(n, generator=generator) < 0.2 for _ in CAUSES]
    cause, fail, ok, _ = assert_compiled_is_eager(partial(verdict, causes=CAUSES), "verdict", CAUSES,
                                                  [current, success, *flags], ("cause", "fail", "success", "reward"),
                                                  atol=0)
    assert 0 < int(fail.sum()) < n and 0 < int(ok.sum())  # a batch with failures, new and old, and successes


def test_the_env_reward_is_maniskills_sparse_reward_of_the_step():
    """The step's reward (from the verdict) is ManiSkill's sparse reward of its info, 0 while flying and -1 once the
    drone fails; an info from elsewhere gets ManiSkill's own computation."""
    env = gym.make("AeroPick-v1", num_envs=1)
    base = env.unwrapped
    env.reset(seed=0)
    dive = torch.zeros(1, base.platform.action_dim)
    dive[:, 2] = -1.0  # straight down, into whatever is below: a collision or the floor fails it
    rewards = []
    for _ in range(120):
        _, reward, terminated, _, info = env.step(dive)
        assert torch.equal(reward, BaseEnv.compute_sparse_reward(base, None, None, info))
        rewards.append(float(reward[0]))
        if bool(terminated.any()):
            break
    assert rewards[0] == 0.0 and rewards[-1] == -1.0 and bool(info["fail"].all())
    foreign = {"success": torch.tensor([True]), "fail": torch.tensor([False])}
    assert base.compute_sparse_reward(None, None, foreign).tolist() == [1.0]
    env.close()
