"""Physical constants of the two aerial platforms, each with its source.

Every gain, mass, limit and rate used by the simulation and the flight controller is defined here and nowhere else.
"Spec" refers to the AeroManip-VLA paper: Sec. 3.2 "Payload-aware Control" (Eqs. vel, force, att), appendix
"Robot platforms" (Table "Parameters of the two platforms") and appendix "Payload-Aware Flight Control".
"PX4 X500" refers to the PX4 Gazebo model `x500_base` / `x500` that the spec keeps the airframe from.

Frames: world z is up; the body frame has x forward, y left, z up, with its origin O at the X500 airframe centre
(the point the virtual joints pivot about and the point the rotor wrench is expressed about).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

# --------------------------------------------------------------------------------------------------------------------
# Rates and command scaling (spec Sec. 3.2 and appendix "Robot platforms")
# --------------------------------------------------------------------------------------------------------------------
PHYSICS_HZ = 240  # "Physics and low-level control are updated at 240 Hz"
CONTROL_HZ = 20  # "while the policy runs at 20 Hz"
PHYSICS_DT = 1.0 / PHYSICS_HZ
MAX_SPEED_MPS = 0.6  # "world-frame linear velocity and yaw-rate commands, bounded by 0.6 m/s and 1 rad/s"
MAX_YAW_RATE_RPS = 1.0
FLIGHT_ACTION_DIMS = 4  # every action starts with vx, vy, vz (x MAX_SPEED_MPS) and yaw rate (x MAX_YAW_RATE_RPS)
GRAVITY = 9.81  # m/s^2, SAPIEN's default scene gravity, so the controller's g equals the simulated one


@dataclass(frozen=True)
class Component:
    """A rigid piece of the airframe link: a point mass (or a body with its own inertia) at a body-frame position."""

    name: str
    mass_kg: float
    position_m: tuple[float, float, float]
    inertia_kgm2: tuple[float, float, float] = (0.0, 0.0, 0.0)  # principal moments about its own COM, body axes


@dataclass(frozen=True)
class RotorSpec:
    """Four rotors in the X500 "X" layout, all spinning in the body x-y plane."""

    arm_m: float = 0.174  # spec: rotor arm length 0.174 m; PX4 X500 rotor joints at (+-0.174, +-0.174)
    disk_radius_m: float = 0.147  # spec: rotor-disk radius 0.147 m (disks reach 0.174 + 0.147 = 0.32 m out)
    height_m: float = 0.06  # PX4 X500: rotor joints 0.06 m above the base link
    disk_thickness_m: float = 0.01  # collision disk; thin, only its footprint matters
    max_thrust_n: float = 8.55  # spec table; = PX4 motorConstant 8.54858e-6 * maxRotVelocity 1000^2
    moment_coefficient_m: float = 0.016  # PX4 X500 momentConstant: rotor drag torque = 0.016 m * thrust
    mass_kg: float = 0.016076923076923075  # PX4 X500 rotor link mass

    @property
    def positions_xy(self) -> tuple[tuple[float, float], ...]:
        """Rotor centres in PX4 order: front-right, back-left, front-left, back-right."""
        a = self.arm_m
        return ((a, -a), (-a, a), (a, a), (-a, -a))

    @property
    def spin_directions(self) -> tuple[int, ...]:
        """+1 for a counter-clockwise rotor (seen from above), whose drag torque on the body is about -z.

        PX4 X500: rotors 0 and 1 turn counter-clockwise, rotors 2 and 3 clockwise.
        """
        return (1, 1, -1, -1)


@dataclass(frozen=True)
class FlightGains:
    """Cascaded velocity-attitude controller parameters (spec Eqs. vel, force, att and the platform table)."""

    velocity_gain: float = 3.0  # Eq. force: clip_acc(3 e_v + xi)
    integral_limit: float = 2.0  # Eq. vel: xi <- clip(xi + e_v dt, -2, 2); arm platform 4 (table)
    horizontal_accel_limit: float = 3.0  # clip_acc: +-3 m/s^2 per horizontal axis; arm platform 4.5 (table)
    vertical_accel_limit: float = 5.0  # clip_acc: +-5 m/s^2 vertically
    k_R: float = 2.5  # Eq. att, unloaded gripper platform (k_R, k_w) = (2.5, 0.55); arm platform (6, 1.0)
    k_w: float = 0.55
    payload_k_R: float = 12.0  # appendix "Payload-Aware Flight Control": gains raised to (12, 1.2) once grasped
    payload_k_w: float = 1.2
    yaw_torque_limit: float = math.inf  # arm platform: 0.12 N m (a grasped door sets the heading)
    grasp_steps_for_payload: int = 3  # "After three grasped control steps, the controller adds the object mass"


@dataclass(frozen=True)
class GripperSpec:
    """1-DoF parallel gripper with long UMI fingers (spec: platform table, row "Fingers" and "Finger drive")."""

    finger_length_m: float = 0.120  # UMI long fingers, 120 mm
    max_opening_m: float = 0.110  # opening 0-110 mm between the finger pads
    drive_stiffness_npm: float = 150.0  # gripper platform 150 N/m; arm platform 1500 N/m
    force_limit_n: float = 5.0  # per finger: gripper platform 5 N; arm platform 15 N
    # Not in the spec: the drive damping. About half of critical damping for a 30 g finger at 150 N/m.
    drive_damping_nspm: float = 2.0
    finger_mass_kg: float = 0.030  # spec appendix: fingers 30 g each (nominal)
    finger_width_m: float = 0.030  # pad width along the body x axis (geometry, not in the spec)
    finger_thickness_m: float = 0.010
    pad_friction: float = 1.0  # UMI TPU fin-ray pads grip well; rigid pads stand in with high friction


@dataclass(frozen=True)
class ArmJointSpec:
    name: str
    lower_rad: float
    upper_rad: float
    torque_limit_nm: float  # spec table: shoulder 3.0, elbow 0.9, wrist 0.5 N m
    # Not in the spec: servo stiffness, damping and armature. The servo PD is explicit (a torque each physics step,
    # so contact mode can switch the shoulder off per env); the armature is the gearbox-reflected rotor inertia of a
    # hobby servo, which also keeps the explicit PD stable at 240 Hz (the joint-space inertia of the bare links is
    # only ~5e-4 kg m^2 at the elbow).
    stiffness_nmprad: float
    damping_nmsprad: float
    armature_kgm2: float


@dataclass(frozen=True)
class ArmSpec:
    """3-DoF arm of the arm platform (spec appendix "Robot platforms", "Arm platform" paragraph and table)."""

    shoulder_position_m: tuple[float, float, float] = (0.02, 0.0, -0.045)  # 2 cm forward of, 4.5 cm below the centre
    upper_arm_length_m: float = 0.22  # link lengths 0.22 / 0.12 / 0.12 m to the grasp point
    forearm_length_m: float = 0.12
    wrist_to_grasp_m: float = 0.12
    joints: tuple[ArmJointSpec, ...] = (
        ArmJointSpec("shoulder_pitch", -0.6, 1.9, 3.0, 80.0, 1.9, 0.01),
        ArmJointSpec("elbow_pitch", -2.6, 2.6, 0.9, 30.0, 0.5, 0.005),
        ArmJointSpec("wrist_roll", -1.75, 1.75, 0.5, 2.0, 0.07, 0.001),
    )
    # Working pose: upper arm pitched up 0.12 rad, forearm level. Positive pitch turns the arm downwards (about +y),
    # so "up 0.12 rad" is -0.12 at the shoulder and +0.12 at the elbow.
    working_pose_rad: tuple[float, float, float] = (-0.12, 0.12, 0.0)
    # Carry pose (not in the spec; the expert's choice for flying between stages): upper arm straight down, forearm
    # level. The grasp point is then 0.26 m ahead of and 0.27 m below the centre, within the rotor disks' outline
    # (0.32 m), so a held object travels under the drone as on the gripper platform, and the footprint that must fit
    # through doorways is the airframe's at any heading instead of an arm 0.47 m long at one heading.
    carry_pose_rad: tuple[float, float, float] = (1.57, -1.57, 0.0)
    # Top-down pose (not in the spec; the expert's choice for picking from and placing on open supports): upper arm
    # level, forearm straight down, fingers pointing down and closing along body y as the gripper platform's do. The
    # grasp point is 0.24 m ahead of and 0.285 m below the centre, inside the rotor disks' outline; the load hangs
    # along the forearm, so the elbow (0.9 N m) carries almost nothing and the shoulder (3.0 N m) holds the spec's
    # heaviest objects (0.41 kg at 0.24 m: about 1.3 N m with the links), where a level forearm holds 0.28 kg.
    top_down_pose_rad: tuple[float, float, float] = (0.0, 1.57, 0.0)
    # Spec appendix "Modelling assumptions": arm link masses 0.17 kg in total plus an 82 g shoulder servo; the split
    # between the three links is nominal (elbow and wrist servos ride on the upper arm and forearm).
    upper_arm_mass_kg: float = 0.08
    forearm_mass_kg: float = 0.05
    wrist_mass_kg: float = 0.04
    shoulder_servo_mass_kg: float = 0.082
    link_thickness_m: float = 0.025
    palm_half_length_m: float = 0.02  # the palm block, centred a third of the way from the wrist joint to the grasp point

    @property
    def palm_to_grasp_m(self) -> float:
        """How far the palm's face stands back from the grasp point along the fingers (0.06 m): a top-down grasp must
        leave the object's top below it."""
        return self.wrist_to_grasp_m * 2 / 3 - self.palm_half_length_m


@dataclass(frozen=True)
class CameraMount:
    """An onboard RGB-D camera (spec: 128x128 RGB-D, platform table rows "Hand camera" and "Down camera")."""

    uid: str
    link: str  # name of the body link the camera rides on
    eye_m: tuple[float, float, float]  # position in that link's frame
    target_m: tuple[float, float, float]  # point the optical axis passes through, same frame
    fov_rad: float = math.radians(90.0)
    width: int = 128
    height: int = 128
    near_m: float = 0.01
    far_m: float = 10.0


@dataclass(frozen=True)
class PlatformSpec:
    """One aerial manipulation platform: airframe, rotors, manipulator, cameras and flight gains."""

    name: str
    total_mass_kg: float  # m0 (spec table)
    rotors: RotorSpec
    gains: FlightGains
    gripper: GripperSpec
    grasp_point_m: tuple[float, float, float]  # tool centre point in the body frame at the working pose
    airframe_components: tuple[Component, ...]
    cameras: tuple[CameraMount, ...]
    arm: ArmSpec | None = None
    airframe_inertia_kgm2: tuple[float, float, float] = (0.02166666666666667, 0.02166666666666667, 0.04000000000000001)
    # PX4 X500 base_link inertia, kept from the source model (spec appendix: "X500 mass and inertia are kept").

    @property
    def thrust_to_weight(self) -> float:
        return 4 * self.rotors.max_thrust_n / (self.total_mass_kg * GRAVITY)

    @property
    def action_dim(self) -> int:
        """4 flight (+ 3 arm) + 1 gripper."""
        return FLIGHT_ACTION_DIMS + (len(self.arm.joints) if self.arm else 0) + 1


# --------------------------------------------------------------------------------------------------------------------
# Component masses. The spec gives m0 per platform and nominal component masses (appendix "Robot platforms").
# The X500 body keeps the source inertia; its mass is the remainder of m0 after the listed components, so the total
# is exactly the table's m0 (gripper: 2.060 kg vs PX4's 2.0 + 4 x 0.016 = 2.064 kg; arm: the listed nominal parts
# add up to 26 g more than the table's 2.58 kg total, and the remainder absorbs that rounding).
# --------------------------------------------------------------------------------------------------------------------
_ROTORS_STOCK = RotorSpec()
_ROTORS_ARM = RotorSpec(max_thrust_n=11.5)  # spec: motors upgraded to 11.5 N per rotor (nominal 150 g added)
_GRIPPER = GripperSpec()
_ARM_GRIPPER = GripperSpec(drive_stiffness_npm=1500.0, force_limit_n=15.0, drive_damping_nspm=6.0)
_ARM = ArmSpec()

GRIPPER_TCP_DEPTH_M = 0.28  # spec: grasp point 0.28 m below the airframe centre
GRIPPER_PALM_Z_M = -(GRIPPER_TCP_DEPTH_M - _GRIPPER.finger_length_m + 0.02)  # finger tips 2 cm below the TCP


def _rotor_components(rotors: RotorSpec, extra_motor_mass_kg: float = 0.0) -> tuple[Component, ...]:
    return tuple(
        Component(f"rotor_{i}", rotors.mass_kg + extra_motor_mass_kg / 4, (x, y, rotors.height_m))
        for i, (x, y) in enumerate(rotors.positions_xy)
    )


def _with_body_remainder(total_mass_kg: float, parts: tuple[Component, ...]) -> tuple[Component, ...]:
    body_mass = total_mass_kg - sum(p.mass_kg for p in parts)
    return (Component("x500_body", body_mass, (0.0, 0.0, 0.0)),) + parts


_GRIPPER_M0 = 2.38  # spec table
_GRIPPER_FINGER_MASS = 2 * _GRIPPER.finger_mass_kg  # fingers are their own links, not airframe components
GRIPPER_PLATFORM = PlatformSpec(
    name="gripper",
    total_mass_kg=_GRIPPER_M0,
    rotors=_ROTORS_STOCK,
    gains=FlightGains(),
    gripper=_GRIPPER,
    grasp_point_m=(0.0, 0.0, -GRIPPER_TCP_DEPTH_M),
    airframe_components=_with_body_remainder(
        _GRIPPER_M0 - _GRIPPER_FINGER_MASS,
        _rotor_components(_ROTORS_STOCK)
        + (
            # spec appendix: adapter 100 g, palm 80 g, cameras and mounts 80 g; all on the body axis so the hover
            # thrusts are equal (the cameras' own masses are lumped at the mount plate).
            Component("gripper_adapter", 0.100, (0.0, 0.0, -0.08), (1.5e-4, 1.5e-4, 3e-5)),
            Component("palm", 0.080, (0.0, 0.0, GRIPPER_PALM_Z_M + 0.01), (1.4e-4, 2e-5, 1.4e-4)),
            Component("cameras_and_mounts", 0.080, (0.0, 0.0, -0.03)),
        ),
    ),
    cameras=(
        CameraMount("drone_front", "airframe", (0.11, 0.0, 0.0), (1.11, 0.0, -0.27)),  # FPV, 15 deg down
        CameraMount("drone_hand", "airframe", (0.05, 0.0, -0.10), (0.0, 0.0, -0.30)),  # below frame, at the jaw
        CameraMount("drone_own", "airframe", (0.09, 0.0, -0.05), (0.60, 0.0, -0.65)),  # under frame, down-forward
    ),
)

_ARM_M0 = 2.58  # spec table
_ARM_LINK_MASS = _ARM.upper_arm_mass_kg + _ARM.forearm_mass_kg + _ARM.wrist_mass_kg + 2 * _ARM_GRIPPER.finger_mass_kg
ARM_PLATFORM = PlatformSpec(
    name="arm",
    total_mass_kg=_ARM_M0,
    rotors=_ROTORS_ARM,
    gains=FlightGains(
        integral_limit=4.0,
        horizontal_accel_limit=4.5,
        k_R=6.0,
        k_w=1.0,
        yaw_torque_limit=0.12,
    ),
    gripper=_ARM_GRIPPER,
    grasp_point_m=(0.47, 0.0, -0.02),  # spec: 0.47 m ahead, 0.02 m below at the working pose
    airframe_components=_with_body_remainder(
        _ARM_M0 - _ARM_LINK_MASS,
        _rotor_components(_ROTORS_ARM, extra_motor_mass_kg=0.150)
        + (
            Component("shoulder_servo", _ARM.shoulder_servo_mass_kg, _ARM.shoulder_position_m, (1e-5, 1e-5, 1e-5)),
            Component("cameras_and_mounts", 0.080, (0.0, 0.0, -0.03)),
        ),
    ),
    cameras=(
        CameraMount("drone_front", "airframe", (0.11, 0.0, 0.0), (1.11, 0.0, -0.27)),
        CameraMount("drone_hand", "wrist", (0.02, 0.0, 0.035), (0.30, 0.0, -0.02)),  # on the wrist, along the fingers
        CameraMount("drone_own", "airframe", (0.12, -0.14, -0.05), (0.47, 0.0, -0.10)),  # right front, side view
    ),
    arm=_ARM,
)

PLATFORMS: Mapping[str, PlatformSpec] = MappingProxyType(
    {GRIPPER_PLATFORM.name: GRIPPER_PLATFORM, ARM_PLATFORM.name: ARM_PLATFORM}
)


def get_platform(name: str) -> PlatformSpec:
    """Look up a platform by name; unknown names raise a one-line error listing the valid ones."""
    try:
        return PLATFORMS[name]
    except KeyError:
        raise ValueError(f"unknown platform {name!r}; valid platforms: {', '.join(PLATFORMS)}") from None


__all__ = [
    "ARM_PLATFORM",
    "CONTROL_HZ",
    "GRAVITY",
    "GRIPPER_PLATFORM",
    "MAX_SPEED_MPS",
    "MAX_YAW_RATE_RPS",
    "FLIGHT_ACTION_DIMS",
    "PHYSICS_DT",
    "PHYSICS_HZ",
    "PLATFORMS",
    "ArmJointSpec",
    "ArmSpec",
    "CameraMount",
    "Component",
    "FlightGains",
    "GripperSpec",
    "PlatformSpec",
    "RotorSpec",
    "get_platform",
]
