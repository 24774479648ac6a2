"""The platform constants against the spec's platform table and control section."""

import math

import pytest

from aerobench.envs.platforms import ARM_PLATFORM, CONTROL_HZ, GRIPPER_PLATFORM, PHYSICS_HZ, get_platform


def test_rates_match_spec():
    assert PHYSICS_HZ == 240 and CONTROL_HZ == 20 and PHYSICS_HZ % CONTROL_HZ == 0


@pytest.mark.parametrize(
    "platform, m0, f_max, twr, gains, acc_xy, xi_limit",
    [
        (GRIPPER_PLATFORM, 2.38, 8.55, 1.46, (2.5, 0.55), 3.0, 2.0),
        (ARM_PLATFORM, 2.58, 11.5, 1.82, (6.0, 1.0), 4.5, 4.0),
    ],
)
def test_platform_table(platform, m0, f_max, twr, gains, acc_xy, xi_limit):
    assert platform.total_mass_kg == m0
    assert sum(c.mass_kg for c in platform.airframe_components) < m0  # the rest is in the finger / arm links
    assert platform.rotors.max_thrust_n == f_max
    assert round(platform.thrust_to_weight, 2) == twr
    assert (platform.gains.k_R, platform.gains.k_w) == gains
    assert (platform.gains.payload_k_R, platform.gains.payload_k_w) == (12.0, 1.2)
    assert platform.gains.horizontal_accel_limit == acc_xy
    assert platform.gains.vertical_accel_limit == 5.0
    assert platform.gains.integral_limit == xi_limit
    assert platform.gains.velocity_gain == 3.0
    assert platform.gains.grasp_steps_for_payload == 3
    assert platform.rotors.arm_m == 0.174 and platform.rotors.disk_radius_m == 0.147
    assert [c.uid for c in platform.cameras] == ["drone_front", "drone_hand", "drone_own"]
    assert all(c.width == c.height == 128 for c in platform.cameras)


def test_rotor_disks_reach_032_m_beyond_the_gripper():
    r = GRIPPER_PLATFORM.rotors
    assert math.isclose(r.arm_m + r.disk_radius_m, 0.321, abs_tol=1e-9)
    assert GRIPPER_PLATFORM.grasp_point_m == (0.0, 0.0, -0.28)


def test_arm_and_gripper_specs():
    arm = ARM_PLATFORM.arm
    assert [(j.lower_rad, j.upper_rad, j.torque_limit_nm) for j in arm.joints] == [
        (-0.6, 1.9, 3.0), (-2.6, 2.6, 0.9), (-1.75, 1.75, 0.5)
    ]
    assert (arm.upper_arm_length_m, arm.forearm_length_m, arm.wrist_to_grasp_m) == (0.22, 0.12, 0.12)
    assert arm.shoulder_position_m == (0.02, 0.0, -0.045)
    assert ARM_PLATFORM.gains.yaw_torque_limit == 0.12 and math.isinf(GRIPPER_PLATFORM.gains.yaw_torque_limit)
    assert (GRIPPER_PLATFORM.gripper.drive_stiffness_npm, GRIPPER_PLATFORM.gripper.force_limit_n) == (150.0, 5.0)
    assert (ARM_PLATFORM.gripper.drive_stiffness_npm, ARM_PLATFORM.gripper.force_limit_n) == (1500.0, 15.0)
    for p in (GRIPPER_PLATFORM, ARM_PLATFORM):
        assert (p.gripper.finger_length_m, p.gripper.max_opening_m) == (0.12, 0.11)
    assert GRIPPER_PLATFORM.action_dim == 5 and ARM_PLATFORM.action_dim == 8


def test_gripper_component_masses_from_spec():
    masses = {c.name: c.mass_kg for c in GRIPPER_PLATFORM.airframe_components}
    assert masses["gripper_adapter"] == 0.100 and masses["palm"] == 0.080 and masses["cameras_and_mounts"] == 0.080
    assert GRIPPER_PLATFORM.gripper.finger_mass_kg == 0.030
    # The X500 body keeps PX4's 2.0 kg + four 16 g rotors to within rounding of the table's 2.38 kg.
    x500 = masses["x500_body"] + sum(m for n, m in masses.items() if n.startswith("rotor_"))
    assert abs(x500 - 2.064) < 0.005


def test_unknown_platform_is_a_one_line_error():
    with pytest.raises(ValueError, match=r"unknown platform 'quad'; valid platforms: gripper, arm"):
        get_platform("quad")
