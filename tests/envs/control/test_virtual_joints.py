"""Q = J^T W and the joint-state to rigid-body-state map of the six virtual joints."""

import torch

from aerobench.envs.control.so3 import matrix_to_euler_zyx, matrix_to_quat_wxyz, quat_rotate, quat_wxyz_to_matrix, vee
from aerobench.envs.control.virtual_joints import airframe_state_from_joints, joint_efforts_from_wrench

torch.manual_seed(1)


def _random_joints(n):
    q = torch.randn(n, 6, dtype=torch.float64)
    q[:, 4:] *= 0.5  # pitch and roll away from gimbal lock
    return q, torch.randn(n, 6, dtype=torch.float64)


def test_joint_efforts_do_the_same_work_as_the_wrench():
    """J^T W is right iff Q . qdot = F . v + tau . omega for every joint velocity (virtual power)."""
    q, qd = _random_joints(64)
    state = airframe_state_from_joints(q, qd)
    F, tau = torch.randn(64, 3, dtype=torch.float64), torch.randn(64, 3, dtype=torch.float64)
    Q = joint_efforts_from_wrench(q, F, tau)
    omega_world = (state.rotation @ state.angular_velocity_body[..., None])[..., 0]
    assert torch.allclose((Q * qd).sum(-1), (F * state.velocity).sum(-1) + (tau * omega_world).sum(-1))


def test_angular_velocity_matches_finite_difference_of_rotation():
    q, qd = _random_joints(16)
    dt = 1e-6
    R0 = airframe_state_from_joints(q, qd).rotation
    R1 = airframe_state_from_joints(q + qd * dt, qd).rotation
    omega_fd = vee((R0.transpose(-1, -2) @ R1 - torch.eye(3, dtype=q.dtype)) / dt)
    assert torch.allclose(airframe_state_from_joints(q, qd).angular_velocity_body, omega_fd, atol=1e-4)


def test_rotation_helpers_round_trip():
    q, _ = _random_joints(32)
    R = airframe_state_from_joints(q, torch.zeros_like(q)).rotation
    yaw, pitch, roll = matrix_to_euler_zyx(R)
    assert torch.allclose(torch.stack([yaw, pitch, roll], -1), torch.atan2(torch.sin(q[:, 3:]), torch.cos(q[:, 3:])))
    assert torch.allclose(quat_wxyz_to_matrix(matrix_to_quat_wxyz(R)), R, atol=1e-9)


def test_quat_rotate_is_the_rotation_matrix_product():
    g = torch.Generator().manual_seed(0)
    q = torch.randn(64, 4, generator=g)
    q = q / q.norm(dim=-1, keepdim=True)
    v = torch.randn(64, 3, generator=g)
    expected = (quat_wxyz_to_matrix(q) @ v[..., None])[..., 0]
    torch.testing.assert_close(quat_rotate(q, v), expected, rtol=1e-5, atol=1e-5)
    torch.testing.assert_close(quat_rotate(q, torch.tensor([0.0, 1.0, 0.0])), quat_wxyz_to_matrix(q)[..., :, 1])
