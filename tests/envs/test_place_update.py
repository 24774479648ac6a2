"""The place evaluator's control step (`skills.place.place_update`): compiled as the eager function, trackers
advanced only where the place is active, and no host synchronization."""

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401
from aerobench.envs.skills.place import PlaceUpdate, place_update_kernel
from aerobench.policies import make_policy
from tests.envs.host_sync import NoHostSync
from tests.envs.kernel_checks import assert_compiled_is_eager

pytestmark = [pytest.mark.usefixtures("aot_cache"), pytest.mark.xdist_group("aot_packages")]  # packages built here go to this run's cache

MINE = 15  # `place_update`'s input position of the mask of envs where the place is active
TRACKERS = 5  # its first outputs: the trackers


def _set_down_inputs():
    """`place_update`'s inputs at a step where the goal support carries the object (its set-down under way)."""
    env = gym.make("AeroPlace-v1", num_envs=1)
    obs, _ = env.reset(seed=0)
    base = env.unwrapped
    policy = make_policy("expert", base)
    policy.reset(torch.arange(1))
    inputs = {}
    evaluator = base.evaluators[0]
    kernel = evaluator._update = place_update_kernel(evaluator._update_law(), "cpu", compile=False)
    real = kernel.fn

    def record(*tensors):
        inputs["last"] = [t.clone() for t in tensors]
        return real(*tensors)

    kernel.fn = record
    try:
        for _ in range(400):
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            if int(info["set_down_steps"][0]) >= 2:
                return env, real, inputs["last"]
            assert not bool(terminated.any() | truncated.any()), "the expert's place ended before its set-down"
    finally:
        kernel.fn = real
    raise AssertionError("no set-down in 400 steps")


def test_compiled_place_update_is_the_eager_one_and_keeps_inactive_trackers(aot_cache):
    env, eager, inputs = _set_down_inputs()
    reference = PlaceUpdate(*assert_compiled_is_eager(eager, "place_evaluator", "test", inputs, PlaceUpdate._fields,
                                                      atol=1e-6))
    assert bool(reference.support_contact.all()) and int(reference.set_down_streak[0]) >= 2
    idle = list(inputs)
    idle[MINE] = torch.zeros_like(inputs[MINE])  # another chain stage is active: the trackers stay
    held = PlaceUpdate(*eager(*idle))
    for name, a, b in zip(PlaceUpdate._fields[:TRACKERS], held, inputs[MINE + 1:]):
        assert torch.equal(a, b), name
    assert torch.equal(held.support_contact, reference.support_contact)  # the signals are the step's all the same
    env.close()


def test_place_update_makes_no_host_sync():
    env, eager, inputs = _set_down_inputs()
    with NoHostSync():
        out = PlaceUpdate(*eager(*inputs))
    assert out.set_down_streak.dtype == torch.long
    env.close()
