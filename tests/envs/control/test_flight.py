"""The controller laws against the spec's equations (Sec. 3.2), without SAPIEN."""

import math

import pytest
import torch

from aerobench.envs.control.flight import (
    FlightMemory,
    FlightParams,
    allocate_rotor_thrusts,
    allocation_matrix,
    attitude_error,
    attitude_torque,
    clip_acceleration,
    collective_thrust,
    desired_force,
    desired_rotation,
    flight_step,
    integrate_yaw,
    rotor_wrench_world,
    velocity_error_and_integral,
)
from aerobench.envs.control.so3 import euler_zyx_to_matrix, rot_x, tilt_angle
from aerobench.envs.control.virtual_joints import AirframeState
from aerobench.envs.platforms import ARM_PLATFORM, GRAVITY, GRIPPER_PLATFORM, PHYSICS_DT

torch.manual_seed(0)


def test_velocity_integral_clips_per_component():
    xi = torch.tensor([[1.99, -1.99, 0.0]])
    e_v, xi_new = velocity_error_and_integral(torch.tensor([[10.0, -10.0, 0.3]]), torch.zeros(1, 3), xi, 0.01, 2.0)
    assert torch.allclose(e_v, torch.tensor([[10.0, -10.0, 0.3]]))
    assert torch.allclose(xi_new, torch.tensor([[2.0, -2.0, 0.003]]))


def test_desired_force_is_mass_times_clipped_acceleration_plus_gravity():
    g = GRIPPER_PLATFORM.gains
    e_v = torch.tensor([[2.0, -0.1, 0.5], [0.0, 0.0, -3.0]])
    xi = torch.tensor([[0.0, 0.0, 0.2], [0.0, 0.0, 0.0]])
    m = torch.tensor([2.38, 2.75])
    f = desired_force(m, e_v, xi, g, GRAVITY)
    expected_acc = torch.tensor([[3.0, -0.3, 1.7], [0.0, 0.0, -5.0]])  # 3*2 -> clipped 3; 3*(-3) -> clipped -5
    assert torch.allclose(f, m[:, None] * (expected_acc + torch.tensor([0, 0, GRAVITY])))
    arm = clip_acceleration(torch.tensor([[9.0, -9.0, 9.0]]), ARM_PLATFORM.gains.horizontal_accel_limit, 5.0)
    assert torch.allclose(arm, torch.tensor([[4.5, -4.5, 5.0]]))


def test_yaw_integration_wraps():
    yaw = integrate_yaw(torch.tensor([math.pi - 0.001]), torch.tensor([1.0]), 0.01)
    assert torch.allclose(yaw, torch.tensor([-math.pi + 0.009]), atol=1e-6)


def test_desired_rotation_aligns_body_z_with_force_and_keeps_heading():
    f = torch.randn(64, 3) + torch.tensor([0, 0, 20.0])
    yaw = (torch.rand(64) - 0.5) * 2 * math.pi
    R = desired_rotation(f, yaw)
    assert torch.allclose(R.transpose(-1, -2) @ R, torch.eye(3).expand(64, 3, 3), atol=1e-5)
    assert torch.allclose(torch.det(R), torch.ones(64), atol=1e-5)
    assert torch.allclose(R[:, :, 2], f / f.norm(dim=-1, keepdim=True), atol=1e-5)
    heading = torch.stack([torch.cos(yaw), torch.sin(yaw), torch.zeros(64)], -1)
    assert torch.allclose((R[:, :, 1] * heading).sum(-1), torch.zeros(64), atol=1e-5)  # b2 = b3 x heading
    assert ((R[:, :, 0] * heading).sum(-1) > 0).all()  # b1 points along the heading
    level = desired_rotation(torch.tensor([[0, 0, 23.0]]), torch.tensor([0.7]))
    assert torch.allclose(level, euler_zyx_to_matrix(torch.tensor([0.7]), torch.zeros(1), torch.zeros(1)), atol=1e-6)


def test_attitude_error_is_the_so3_error():
    theta = torch.tensor([0.3])
    assert torch.allclose(attitude_error(rot_x(theta), torch.eye(3)[None]), torch.tensor([[math.sin(0.3), 0, 0]]))
    R = euler_zyx_to_matrix(torch.randn(8), torch.randn(8) * 0.3, torch.randn(8) * 0.3)
    assert torch.allclose(attitude_error(R, R), torch.zeros(8, 3), atol=1e-6)


@pytest.mark.parametrize("platform", [GRIPPER_PLATFORM, ARM_PLATFORM])
def test_attitude_torque_is_pd_with_platform_gains(platform):
    R = euler_zyx_to_matrix(torch.randn(4), torch.randn(4) * 0.2, torch.randn(4) * 0.2)
    R_des = euler_zyx_to_matrix(torch.randn(4), torch.randn(4) * 0.2, torch.randn(4) * 0.2)
    w, w_des = torch.randn(4, 3), torch.randn(4, 3)
    k_R = torch.full((4,), platform.gains.k_R)
    k_w = torch.full((4,), platform.gains.k_w)
    tau = attitude_torque(R, R_des, w, w_des, k_R, k_w)
    assert torch.allclose(tau, -platform.gains.k_R * attitude_error(R, R_des) - platform.gains.k_w * (w - w_des))


def test_collective_thrust_projects_on_body_z():
    R = rot_x(torch.tensor([0.5]))
    f = torch.tensor([[0.0, 0.0, 10.0]])
    assert torch.allclose(collective_thrust(f, R), torch.tensor([10.0 * math.cos(0.5)]))


def test_allocation_inverts_and_saturates():
    rotors = GRIPPER_PLATFORM.rotors
    A = allocation_matrix(rotors)
    hover = allocate_rotor_thrusts(torch.tensor([23.35]), torch.zeros(1, 3), torch.linalg.inv(A), rotors.max_thrust_n)
    assert torch.allclose(hover, torch.full((1, 4), 23.35 / 4))
    T = torch.rand(256) * 60 - 10
    tau = torch.randn(256, 3) * 5
    f = allocate_rotor_thrusts(T, tau, torch.linalg.inv(A), rotors.max_thrust_n)
    assert f.min() >= 0.0 and f.max() <= rotors.max_thrust_n
    small = allocate_rotor_thrusts(torch.tensor([20.0]), torch.tensor([[0.1, -0.1, 0.01]]), torch.linalg.inv(A), 8.55)
    assert torch.allclose(small @ A.T, torch.tensor([[20.0, 0.1, -0.1, 0.01]]), atol=1e-5)


def test_rotor_torques_follow_geometry():
    A = allocation_matrix(GRIPPER_PLATFORM.rotors)
    front = torch.tensor([[1.0, 0.0, 1.0, 0.0]])  # rotors 0 (front right) and 2 (front left)
    _, tau = rotor_wrench_world(front, torch.eye(3)[None], A)
    assert tau[0, 1] < 0  # more thrust at the front pitches the nose up: negative torque about +y
    assert abs(float(tau[0, 0])) < 1e-6
    F, _ = rotor_wrench_world(torch.full((1, 4), 2.0), rot_x(torch.tensor([0.2])), A)
    assert torch.allclose(F, 8.0 * rot_x(torch.tensor([0.2]))[:, :, 2])


def _random_state(n):
    R = euler_zyx_to_matrix(torch.randn(n) * 3, torch.randn(n) * 0.5, torch.randn(n) * 0.5)
    return AirframeState(torch.randn(n, 3), torch.randn(n, 3) * 2, R, torch.randn(n, 3) * 3)


@pytest.mark.parametrize("platform", [GRIPPER_PLATFORM, ARM_PLATFORM])
def test_flight_step_respects_saturations_under_extreme_commands(platform):
    params = FlightParams.from_platform(platform)
    memory = FlightMemory.initial(128, params)
    for _ in range(500):
        out, memory = flight_step(_random_state(128), torch.randn(128, 3) * 50, torch.randn(128) * 20, memory, params)
        assert out.rotor_thrusts.min() >= 0.0 and out.rotor_thrusts.max() <= platform.rotors.max_thrust_n
        assert memory.xi.abs().max() <= platform.gains.integral_limit
        if math.isfinite(platform.gains.yaw_torque_limit):
            assert out.torque_body_cmd[:, 2].abs().max() <= platform.gains.yaw_torque_limit + 1e-6


def test_hover_equilibrium_gives_equal_thrusts():
    params = FlightParams.from_platform(GRIPPER_PLATFORM)
    memory = FlightMemory.initial(1, params)
    state = AirframeState(torch.zeros(1, 3), torch.zeros(1, 3), torch.eye(3)[None], torch.zeros(1, 3))
    out, memory = flight_step(state, torch.zeros(1, 3), torch.zeros(1), memory, params)
    assert torch.allclose(out.rotor_thrusts, torch.full((1, 4), 2.38 * GRAVITY / 4))
    assert torch.allclose(out.force_world, torch.tensor([[0, 0, 2.38 * GRAVITY]]))
    assert float(tilt_angle(out.rotation_des)) < 1e-6
    assert params.dt == PHYSICS_DT
