"""What the step context reads on physx_cpu without ManiSkill's batched wrappers (the contact reader's one pass over
PhysX's contact list, body poses from their SAPIEN entity) and the state observation flattened without ManiSkill's
walk of the dict, against ManiSkill's own."""

import gymnasium as gym
import pytest
import torch
from mani_skill.utils import common

import aerobench.envs  # noqa: F401
from aerobench.envs.base_env import state_leaves
from aerobench.envs.poses import pose_of, raw_quats_of
from aerobench.policies import make_policy


def test_the_cpu_reader_gives_maniskills_per_pair_and_net_forces_while_an_object_is_held():
    env = gym.make("AeroPick-v1", num_envs=1)
    obs, _ = env.reset(seed=0)
    base = env.unwrapped
    policy = make_policy("expert", base)
    policy.reset(torch.arange(1))
    compared = 0
    for _ in range(300):
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        if bool(terminated.any() | truncated.any()):
            break
        if not bool(info["is_grasped"].any()):
            continue
        readout, scene, target = base.contacts.read(), base.scene, base.target
        on_target = torch.stack([scene.get_pairwise_contact_forces(f, target) for f in base.agent.finger_links], 1)
        links = base.agent.robot.get_net_contact_forces(base.contacts.link_names)
        assert float(on_target.norm(dim=-1).min()) > 0.5  # both fingers squeeze the object: a real comparison
        torch.testing.assert_close(readout.finger_on_target, on_target, rtol=1e-5, atol=1e-4)
        torch.testing.assert_close(readout.target_net, target.get_net_contact_forces(), rtol=1e-5, atol=1e-4)
        torch.testing.assert_close(readout.link_forces, links, rtol=1e-5, atol=1e-4)
        for body in (*base.agent.finger_links, base.agent.grasp_link, target):
            assert torch.equal(pose_of(body).raw_pose, body.pose.raw_pose)
        fingers = base.agent.finger_links
        assert torch.equal(raw_quats_of(fingers), torch.stack([f.pose.q for f in fingers], 1))
        compared += 1
    # the reader keeps the route of each body pair it met: a pair is the same two wrappers at every step, so the
    # memo holds the few pairs that touched, not one entry per step
    assert 0 < len(base.contacts._routes) <= 64, len(base.contacts._routes)
    env.close()
    assert compared >= 10, compared


def test_the_cpu_reader_gives_maniskills_finger_forces_from_a_fixtures_handle_parts():
    env = gym.make("AeroOpen-v1", num_envs=1, setting="PrepareGroceries")
    obs, _ = env.reset(seed=0)
    base = env.unwrapped
    policy = make_policy("expert", base)
    policy.reset(torch.arange(1))
    scene, fingers, handles = base.scene, base.agent.finger_links, base.contacts.handles
    assert handles
    compared = 0
    for _ in range(400):
        obs, _, terminated, truncated, _ = env.step(policy.act(obs))
        if bool(terminated.any() | truncated.any()):
            break
        readout = base.contacts.read()
        on_handle = sum(torch.stack([scene.get_pairwise_contact_forces(f, h) for f in fingers], 1) for h in handles)
        torch.testing.assert_close(readout.finger_on_handle, on_handle, rtol=1e-5, atol=1e-4)
        torch.testing.assert_close(readout.link_forces, base.agent.robot.get_net_contact_forces(base.contacts.link_names),
                                   rtol=1e-5, atol=1e-4)
        compared += int(float(on_handle.norm(dim=-1).max()) > 0.5)  # a finger pushes a handle part: a real comparison
    env.close()
    assert compared >= 5, compared


@pytest.mark.parametrize("env_id, kwargs", [("AeroFly-v1", {}), ("AeroPick-v1", {}), ("AeroPlace-v1", {}),
                                            ("AeroPick-v1", {"setting": "TidyHouse", "platform": "arm"})])
def test_the_state_observation_is_maniskills_flattening_of_the_same_dict(env_id, kwargs):
    """`AerialEnv._flatten_raw_obs` hstacks the state dict's leaves itself: the same tensor, dtype and order as
    ManiSkill's `flatten_state_dict`, over steps where the grasp and contact signals change."""
    env = gym.make(env_id, num_envs=1, obs_mode="state", **kwargs)
    base = env.unwrapped
    obs, _ = env.reset(seed=1)
    policy = make_policy("expert", base) if env_id != "AeroFly-v1" else None
    if policy is not None:
        policy.reset(torch.arange(1))
    action = torch.zeros(1, base.platform.action_dim)
    for _ in range(40):
        obs, *_ = env.step(policy.act(obs) if policy is not None else action)
        raw = base.get_obs(base.get_info(), unflattened=True)
        reference = common.flatten_state_dict(raw, use_torch=True, device=base.device)
        ours = base._flatten_raw_obs(raw)
        assert ours.dtype == reference.dtype and torch.equal(ours, reference)
        assert torch.equal(obs, ours)
    env.close()


def test_state_leaves_leaves_anything_but_tensors_to_maniskill():
    t = torch.zeros(2, 3)
    assert [x.shape for x in state_leaves({"a": {"b": t, "c": torch.ones(2)}, "d": t})] == [(2, 3), (2, 1), (2, 3)]
    assert state_leaves({"a": {"b": t, "c": 1.0}}) is None
    assert state_leaves({"a": {}}) is None


def test_a_step_context_keeps_the_gripper_command_it_read_through_a_reset():
    """The step context holds the env's gripper command tensor itself (no copy per step): the env replaces it and
    never writes into it, so a context kept past a reset still says what was commanded."""
    env = gym.make("AeroPick-v1", num_envs=1, obs_mode="state")
    base = env.unwrapped
    env.reset(seed=0)
    close = torch.zeros(1, base.platform.action_dim)
    close[:, -1] = -1.0
    env.step(close)
    ctx = base.current_step_context()
    assert float(ctx.gripper_command[0]) == -1.0
    env.reset(seed=1)
    assert float(base.current_step_context().gripper_command[0]) == 1.0  # a reset opens the gripper
    assert float(ctx.gripper_command[0]) == -1.0
    env.close()
