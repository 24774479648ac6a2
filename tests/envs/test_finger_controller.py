"""The fingers' controller: ManiSkill's mimic PD controller, a repeated command not applied again on physx_cpu."""

import gymnasium as gym
import numpy as np
import pytest
import torch
from mani_skill.agents.controllers import PDJointPosMimicController

import aerobench.envs  # noqa: F401
from aerobench.envs.agents.finger_controller import FingerController, FingerControllerConfig
from aerobench.policies import make_policy


def _finger_targets(base) -> np.ndarray:
    return np.array([float(j._objs[0].get_drive_target()[0]) for j in base.agent.controller.controllers["gripper"].joints])


def test_a_repeated_command_is_skipped_a_new_one_or_a_reset_applies(monkeypatch):
    applied = []
    plain = PDJointPosMimicController.set_action
    monkeypatch.setattr(PDJointPosMimicController, "set_action", lambda self, a: (applied.append(a.clone()), plain(self, a)))
    env = gym.make("AeroFly-v1", obs_mode="state", scene="empty")
    env.reset(seed=0)
    base = env.unwrapped
    assert isinstance(base.agent.controller.controllers["gripper"], FingerController)
    action = torch.zeros(1, base.platform.action_dim)
    action[:, -1] = 1.0  # open
    env.step(action)
    open_targets = _finger_targets(base)
    upper = base.agent.controller.controllers["gripper"].config.upper
    assert len(applied) == 1 and open_targets == pytest.approx([upper, upper])  # ManiSkill's scaling, both fingers
    env.step(action.clone())  # the same command: ManiSkill's path not run, PhysX keeps its targets
    assert len(applied) == 1 and np.array_equal(_finger_targets(base), open_targets)
    action[:, -1] = -1.0  # close
    env.step(action)
    assert len(applied) == 2 and _finger_targets(base) == pytest.approx([0.0, 0.0])
    fingers = base.agent.controller.controllers["gripper"]
    fingers.joints[0]._objs[0].set_drive_target(np.full(1, 0.01, dtype=np.float32))  # e.g. another mode's controller
    env.step(action)  # the same command, but PhysX no longer holds its targets: applied again
    assert len(applied) == 3 and _finger_targets(base) == pytest.approx([0.0, 0.0])
    env.reset(seed=1)
    env.step(action)  # after a reset the first command applies, equal or not to the last one
    assert len(applied) == 4
    env.close()


def test_an_expert_episode_is_the_same_with_every_command_applied():
    """Skipping a repeated command changes nothing: an expert Pick episode, bitwise, against ManiSkill's path."""
    runs = []
    for skip in (True, False):
        env = gym.make("AeroPick-v1", num_envs=1, obs_mode="state")
        obs, _ = env.reset(seed=0)
        base = env.unwrapped
        fingers = base.agent.controller.controllers["gripper"]
        applied = []
        if not skip:  # the agent hands the fingers their command as host floats on physx_cpu: each one applied
            fingers.set_action_values = lambda v, c=fingers, applied=applied: (
                applied.append(v), PDJointPosMimicController.set_action(c, torch.tensor([v])))
        policy = make_policy("expert", base)
        policy.reset(torch.arange(1))
        actions, success = [], []
        for _ in range(200):
            action = policy.act(obs)
            obs, _, terminated, truncated, info = env.step(action)
            actions.append(action.clone())
            success.append(bool(info["success"].any()))
            if bool(terminated.any() | truncated.any()):
                break
        runs.append((torch.cat(actions), success, obs.clone()))
        assert len(applied) == (0 if skip else len(actions))
        env.close()
    (a, s, o), (b, t, p) = runs
    assert s[-1] and s == t and torch.equal(a, b) and torch.equal(o, p)
    assert len(torch.unique(a[:, -1])) < len(a) // 4  # the expert holds its gripper command: most steps were skipped


def test_a_configuration_whose_targets_move_by_themselves_is_refused():
    with pytest.raises(ValueError, match="use_delta and interpolate must be False"):
        config = FingerControllerConfig(["finger_left", "finger_right"], 0.0, 0.05, 100.0, 1.0, interpolate=True,
                                        mimic={"finger_right": {"joint": "finger_left"}})
        env = gym.make("AeroFly-v1", obs_mode="state", scene="empty")
        try:
            config.controller_cls(config, env.unwrapped.agent.robot, 20, 240, scene=env.unwrapped.scene)
        finally:
            env.close()
