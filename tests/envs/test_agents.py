"""The two platforms as ManiSkill agents on physx_cpu: mass, geometry, cameras, actions, bad input."""

import math

import gymnasium as gym
import numpy as np
import pytest
import torch
from mani_skill.agents.controllers import PDJointPosMimicController

import aerobench.envs  # noqa: F401
from aerobench.envs.agents import NonFiniteActionError
from aerobench.envs.agents.airframe import VIRTUAL_LINK_NAMES
from aerobench.envs.agents.finger_controller import FingerController
from aerobench.envs.flight_test import articulated_mass_properties
from aerobench.envs.platforms import MAX_SPEED_MPS, MAX_YAW_RATE_RPS


@pytest.fixture(scope="module", params=["gripper", "arm"])
def env(request):
    env = gym.make("AeroFly-v1", obs_mode="state", scene="empty", platform=request.param)
    env.reset(seed=0)
    yield env.unwrapped
    env.close()


def test_articulated_mass_is_m0_and_virtual_links_are_negligible(env):
    mass, _, inertia = articulated_mass_properties(env.agent)
    assert abs(mass - env.platform.total_mass_kg) < 1e-4
    virtual = sum(float(link._objs[0].mass) for link in env.agent.robot.links if link.name in VIRTUAL_LINK_NAMES)
    assert virtual / mass < 5e-4
    assert np.all(np.linalg.eigvalsh(inertia) > 0.02)  # X500 inertia (0.0217 / 0.04) plus the manipulator


def test_six_virtual_joints_then_manipulator_joints(env):
    names = list(env.agent.robot.active_joints_map)
    assert names[:6] == ["root_x", "root_y", "root_z", "root_yaw", "root_pitch", "root_roll"]
    expected = ["shoulder_pitch", "elbow_pitch", "wrist_roll"] if env.platform.arm else []
    assert names[6:] == expected + ["finger_left", "finger_right"]
    assert env.action_space.shape == (env.platform.action_dim,)


def test_grasp_point_where_the_spec_puts_it(env):
    state = env.agent.airframe_state()
    offset = env.agent.tcp_pose.p[0] - state.position[0]
    expected = torch.tensor(env.platform.grasp_point_m)
    # the arm sags a few millimetres under its own weight from the ideal working pose
    assert torch.allclose(offset, expected, atol=0.012), offset


def test_rotor_disks_are_collision_shapes(env):
    airframe = env.agent.airframe_link._objs[0]
    disks = [s for s in airframe.collision_shapes if type(s).__name__ == "PhysxCollisionShapeCylinder"]
    assert len(disks) == 4
    assert all(math.isclose(s.radius, 0.147, abs_tol=1e-6) for s in disks)
    centres = sorted((round(float(s.local_pose.p[0]), 3), round(float(s.local_pose.p[1]), 3)) for s in disks)
    assert centres == [(-0.174, -0.174), (-0.174, 0.174), (0.174, -0.174), (0.174, 0.174)]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_action_names_the_env(env, bad):
    action = np.zeros(env.platform.action_dim, dtype=np.float32)
    action[2] = bad
    with pytest.raises(NonFiniteActionError, match=r"env index 0"):
        env.step(action)


def test_finite_actions_whose_sum_overflows_are_taken(env):
    """The check sums the action first: finite values whose float32 sum overflows still reach the controller (it
    clamps them to [-1, 1]), as any finite action does."""
    action = np.zeros(env.platform.action_dim, dtype=np.float32)
    action[:2] = np.finfo(np.float32).max
    assert not np.isfinite(torch.as_tensor(action).sum().item())
    env.step(action)
    assert torch.equal(env.agent.body_controller.velocity_cmd[0, :2], torch.full((2,), MAX_SPEED_MPS))


def test_the_flight_command_is_the_clipped_action_scaled(env):
    """The body controller writes each command into one buffer that the fused step reads through `velocity_cmd` and
    `yaw_rate_cmd`: the numbers are the spec's bounds times the clipped action, to the bit, and a reset zeroes them."""
    body = env.agent.body_controller
    read_by_the_step = body.velocity_cmd, body.yaw_rate_cmd
    action = np.zeros(env.platform.action_dim, dtype=np.float32)
    action[:4] = [0.3, -2.0, 0.7071, -0.123]
    env.step(action)
    clipped = torch.clamp(torch.as_tensor(action[:4]), -1.0, 1.0)
    assert torch.equal(body.velocity_cmd[0], clipped[:3] * MAX_SPEED_MPS)
    assert torch.equal(body.yaw_rate_cmd, clipped[3:] * MAX_YAW_RATE_RPS)
    assert body.velocity_cmd is read_by_the_step[0] and body.yaw_rate_cmd is read_by_the_step[1]
    env.reset(seed=0)
    assert not body.velocity_cmd.any() and not body.yaw_rate_cmd.any()


def test_the_action_read_as_host_floats_sets_what_the_controllers_tensor_path_sets(env):
    """On physx_cpu the agent reads the one env's action as host floats and hands each controller its columns
    (`set_action_values`); ManiSkill's combined controller slices the tensor and each controller clips and scales it.
    Both give the same flight command, arm targets and finger drive targets, to the bit, for actions inside and
    outside [-1, 1]."""
    agent, body = env.agent, env.agent.body_controller
    fingers = agent.controller.controllers["gripper"]
    generator = torch.Generator().manual_seed(0)

    def applied():
        targets = [float(j._objs[0].get_drive_target()[0]) for j in fingers.joints]
        return body._command.clone(), body.arm_target.clone(), targets

    for _ in range(20):
        action = torch.rand(1, env.platform.action_dim, generator=generator) * 3.0 - 1.5
        agent.set_action(action)
        by_host = applied()
        fingers.reset()  # the tensor path must apply the fingers' command, not find it held
        agent.controller.set_action(action)
        by_tensors = applied()
        assert torch.equal(by_host[0], by_tensors[0]) and torch.equal(by_host[1], by_tensors[1])
        assert by_host[2] == by_tensors[2]
    assert agent._host_routes() is not None  # (physx_cpu: the host path is the one taken)


def test_three_onboard_rgbd_cameras():
    env = gym.make("AeroFly-v1", obs_mode="rgbd", scene="room", platform="gripper")
    obs, _ = env.reset(seed=0)
    cams = obs["sensor_data"]
    assert set(cams) == {"drone_front", "drone_hand", "drone_own"}
    for cam in cams.values():
        assert cam["rgb"].shape == (1, 128, 128, 3) and cam["depth"].shape == (1, 128, 128, 1)
        assert cam["rgb"].float().std() > 1.0  # the room is visible, not a blank image
    env.close()


def test_the_heading_is_taken_once_after_each_reset(env):
    """A reset arms the heading sync: the first physics step takes the airframe's yaw as the held heading, and the
    flags stay clear after it, until the next reset arms them again."""
    base = env
    bc = base.agent.body_controller
    hover = torch.zeros(1, base.action_space.shape[-1])
    for yaw in (0.7, -1.2):
        env.reset(seed=0)
        q = base.agent.robot.get_qpos().clone()
        q[:, 3] = yaw  # root_yaw: a start at another heading
        base.agent.robot.set_qpos(q)
        assert bool(bc._needs_yaw_sync.all())
        for _ in range(3):
            env.step(hover)
            assert not bool(bc._needs_yaw_sync.any())
        assert float(bc.memory.yaw_des[0]) == pytest.approx(yaw, abs=1e-3)  # held there, not at the last episode's


def test_the_body_controller_is_the_only_one_between_physics_steps(env):
    """`AerialAgent.before_simulation_step` calls the body controller alone: every control mode's other controllers
    must have nothing to do between physics steps."""
    for mode, config in env.agent._controller_configs.items():
        controllers = {k: v for k, v in config.items() if k != "balance_passive_force"}
        assert set(controllers) == {"body", "gripper"}, mode
        assert controllers["gripper"].controller_cls is FingerController, mode
    assert FingerController.before_simulation_step is not PDJointPosMimicController.before_simulation_step


@pytest.mark.xdist_group("aot_packages")  # the flight step's packages: built once, by tests/envs/control/test_fused.py
@pytest.mark.parametrize("platform", ["gripper", "arm"])
def test_the_controller_state_handed_out_and_taken_in_is_a_copy(platform, monkeypatch, aot_cache):
    """The compiled 240 Hz loop updates the controller memory's integrator and heading in place: a state read from
    the body controller, or one given to it, must not change as the drone flies on."""
    monkeypatch.setenv("AEROBENCH_COMPILE", "1")
    env = gym.make("AeroFly-v1", obs_mode="state", scene="empty", platform=platform)
    env.reset(seed=0)
    base = env.unwrapped
    body = base.agent.body_controller
    climb = torch.zeros(1, base.platform.action_dim)
    climb[:, 2], climb[:, 3] = 0.5, 0.3  # climb and turn: the vertical integrator and the heading move
    for _ in range(2):
        env.step(climb)
    assert body.step_fn.kernels["efforts_in_place"].backend == "compiled ahead of time"
    state = body.get_state()
    kept = {k: v.clone() for k, v in state.items()}
    for _ in range(3):
        env.step(climb)
    assert not torch.equal(body.memory.xi, kept["xi"])  # the memory moved on ...
    assert all(torch.equal(state[k], kept[k]) for k in state)  # ... the state read before did not
    body.set_state(state)
    for _ in range(3):
        env.step(climb)
    assert all(torch.equal(state[k], kept[k]) for k in state)  # nor the state given to it
    env.close()
