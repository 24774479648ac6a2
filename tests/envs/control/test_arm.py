"""Arm-platform extras: kinematics, weight-moment feedforward, servos and contact mode."""

import math

import pytest
import torch

from aerobench.envs.control.arm import (
    ArmParams,
    arm_point_positions_body,
    arm_servo_torques,
    arm_weight_feedforward_body,
)
from aerobench.envs.control.so3 import rot_y
from aerobench.envs.platforms import ARM_PLATFORM, GRAVITY

ARM = ArmParams.from_spec(ARM_PLATFORM.arm, ARM_PLATFORM.gripper)
WORKING = torch.tensor([ARM_PLATFORM.arm.working_pose_rad])


def test_working_pose_puts_grasp_point_047_ahead_002_below():
    grasp = arm_point_positions_body(WORKING, ARM_PLATFORM.arm)["grasp"][0]
    assert abs(float(grasp[0]) - 0.47) < 0.01 and abs(float(grasp[2]) + 0.02) < 0.002 and float(grasp[1]) == 0.0


def test_feedforward_cancels_about_07_nm_with_the_arm_extended():
    level = torch.eye(3)[None]
    tau = arm_weight_feedforward_body(level, torch.zeros(1, 3), ARM, GRAVITY)[0]
    # the arm hangs forward: its weight pitches the nose down (+y torque), the feedforward pushes back (-y)
    assert float(tau[1]) < 0 and abs(float(tau[0])) < 1e-9 and abs(float(tau[2])) < 1e-9
    assert 0.6 < abs(float(tau[1])) < 0.8
    # independent of the airframe tilt only through R: pitching the body with the arm rotates the moment arm
    tilted = arm_weight_feedforward_body(rot_y(torch.tensor([0.3])), torch.zeros(1, 3), ARM, GRAVITY)[0]
    assert abs(float(tilted[1]) - float(tau[1]) * math.cos(0.3)) < 0.05


def test_feedforward_adds_the_carried_payload_at_the_grasp_point():
    level = torch.eye(3)[None].expand(2, 3, 3)
    q = WORKING.expand(2, 3)
    bare = arm_weight_feedforward_body(level, q, ARM, GRAVITY)
    loaded = arm_weight_feedforward_body(level, q, ARM, GRAVITY, torch.tensor([0.0, 0.4]))
    assert torch.allclose(loaded[0], bare[0])
    grasp_x = float(arm_point_positions_body(WORKING, ARM_PLATFORM.arm)["grasp"][0, 0])
    # 0.4 kg at the grasp point 0.47 m ahead: 1.8 N m more against the nose-down moment
    assert float(loaded[1, 1] - bare[1, 1]) == pytest.approx(-0.4 * GRAVITY * grasp_x, rel=1e-5)


def test_servos_are_torque_limited_and_shoulder_goes_limp_in_contact_mode():
    q = torch.zeros(2, 3)
    target = torch.tensor([[1.5, 2.0, 1.5], [1.5, 2.0, 1.5]])
    tau = arm_servo_torques(q, torch.zeros(2, 3), target, ARM, torch.tensor([False, True]))
    assert torch.allclose(tau[0], torch.tensor([3.0, 0.9, 0.5]))
    assert torch.allclose(tau[1], torch.tensor([0.0, 0.9, 0.5]))
