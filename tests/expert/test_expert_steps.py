"""The experts' control steps as pure functions (`expert.pick.pick_step`, `expert.place.place_step`): compiled as the
eager functions, on both platforms, with the route follower, and with no host synchronization."""

from functools import partial

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401
from aerobench.expert.pick import PickLaw, PickPhase, PickStep, _flat_pick_step
from aerobench.expert.place import PlaceLaw, PlacePhase, PlaceStep, _flat_place_step
from aerobench.policies import make_policy
from tests.envs.host_sync import NoHostSync
from tests.envs.kernel_checks import assert_compiled_is_eager

pytestmark = [pytest.mark.usefixtures("aot_cache"), pytest.mark.xdist_group("aot_packages")]  # packages built here go to this run's cache


def _expert_in_phase(platform: str, phase, seed: int = 0, steps: int = 300, env_id: str = "AeroPick-v1"):
    env = gym.make(env_id, num_envs=1, platform=platform)
    obs, _ = env.reset(seed=seed)
    policy = make_policy("expert", env.unwrapped)
    policy.reset(torch.arange(1))
    expert = policy.controller.experts[0]
    for _ in range(steps):
        if int(expert.phase[0]) == phase:
            return env, expert
        obs, *_ = env.step(policy.act(obs))
    raise AssertionError(f"the expert never reached {phase.name}")


# one package per case (about 20 s to build): the route follower's pointer with the gripper, the arm's reach without
@pytest.mark.parametrize("platform, seed, phase, routed",
                         [("gripper", 0, PickPhase.DESCEND, True), ("arm", 5, PickPhase.LIFT, False)])
def test_the_compiled_pick_step_is_the_eager_one(platform, seed, phase, routed):
    env, expert = _expert_in_phase(platform, phase, seed)
    tensors = expert.step_inputs()
    law = PickLaw(expert.has_arm, routed, expert.platform.arm, float(expert.max_yaw_rate), float(expert.yaw_gain))
    step = PickStep(*assert_compiled_is_eager(partial(_flat_pick_step, law=law), "pick_expert", law, tensors,
                                              PickStep._fields))
    assert int(step.phase[0]) in (phase, phase + 1)  # a real step of that phase (it may move on)
    env.close()


def test_the_pick_step_makes_no_host_sync():
    env, expert = _expert_in_phase("gripper", PickPhase.ALIGN)
    tensors = expert.step_inputs()
    law = PickLaw(False, True, None, float(expert.max_yaw_rate), float(expert.yaw_gain))
    with NoHostSync():
        action = PickStep(*_flat_pick_step(*tensors, law=law)).action
    assert action.shape == (1, env.unwrapped.platform.action_dim)
    env.close()


@pytest.mark.parametrize("platform, seed, phase", [("gripper", 0, PlacePhase.DESCEND), ("arm", 1, PlacePhase.DESCEND)])
def test_the_compiled_place_step_is_the_eager_one(platform, seed, phase):
    env, expert = _expert_in_phase(platform, phase, seed, env_id="AeroPlace-v1")
    tensors = expert.step_inputs()
    law = PlaceLaw(expert.has_arm, True, float(expert.max_yaw_rate), float(expert.yaw_gain))  # with the side grasp
    step = PlaceStep(*assert_compiled_is_eager(partial(_flat_place_step, law=law), "place_expert", law, tensors,
                                               PlaceStep._fields))
    assert int(step.phase[0]) in (phase, phase + 1)
    with NoHostSync():
        _flat_place_step(*tensors, law=law)
    env.close()


def test_the_expert_in_an_env_without_a_task_is_a_clear_error():
    env = gym.make("AeroFly-v1", num_envs=1, scene="empty")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="the expert acts in the skill and task envs"):
        make_policy("expert", env.unwrapped)
    env.close()
