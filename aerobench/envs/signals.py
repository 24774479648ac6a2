"""The signals every skill env computes at each control step, as one pure function of the step's reads.

`shared_signals` takes what the simulation holds (joint positions and velocities, the grasp link's and the fingers'
poses, the contact forces of `contacts.ContactReadout`, the target object's pose and velocity) and the env's
constants, and returns the airframe state, the tool centre point, the grasp and support checks, the flight envelope,
the airframe's clearance from the scene's boxes and the object's motion since the episode started: everything
`skills.base.AeroSkillEnv.step_context` and `evaluate()` share. No Python branch on a tensor value and no
tensor-to-Python conversion, so one code path serves a batch of GPU envs and, compiled by `kernels.Kernel`, one
physx_cpu env as one call instead of about 250 small ops (a dispatch each, which is what they cost with one env).
"""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path
from typing import NamedTuple

import torch

from ..accel import Kernel, shared_kernel
from .checks import SafetyLimits, consecutive, flight_envelope_flags, is_pinched, nontarget_contact_force, support_force
from .control.so3 import quat_rotate, quat_wxyz_to_matrix, tilt_angle
from .control.virtual_joints import AirframeState, airframe_state_from_joints, joint_columns
from .geometry import body_points_to_world, min_distance_to_boxes
from .observations import GRASP_CONFIRM_STEPS, proprio_state

GRASP_FORCE_N = 0.5  # a grasp: both fingers pressed by the object with at least this force
HELD_FORCE_N = 0.1  # spec (chained evaluation, Open/Close release): "both fingers exceed 0.1 N"
SUPPORTED_WEIGHT_FRACTION = 0.3  # support evidence: the non-finger contacts carry this share of the weight
UPRIGHT_COS = math.cos(math.radians(15.0))
GRAVITY_MPS2 = 9.81
ENVELOPE_FLAGS = ("fail_tilt", "fail_low", "fail_high", "fail_workspace")


class SignalConstants(NamedTuple):
    """What `shared_signals` needs of the env besides tensors (hashable: part of a compiled kernel's key)."""

    tcp_offset: tuple[float, float, float]  # the tool centre point in the grasp link's frame
    finger_idx: tuple[int, int]  # the fingers' rows in the contact readout's link forces
    airframe_idx: int
    proxy_radius: float  # subtracted from the proxy points' distance (`geometry.drone_proxy_points_body`)
    safety: SafetyLimits
    has_target: bool
    virtual_joints: tuple[int, ...]  # the six virtual joints' columns of the articulation's joint vectors
    finger_joints: tuple[int, int]  # the left and right finger joints' columns
    arm_joints: tuple[int, ...]  # the arm's joint columns (none on the gripper platform)


class SharedSignals(NamedTuple):
    """`(N, ...)` tensors; the object's fields are None without a target object."""

    position: torch.Tensor  # (N, 3) airframe centre
    velocity: torch.Tensor  # (N, 3) its linear velocity
    rotation: torch.Tensor  # airframe, body to world
    angular_velocity_body: torch.Tensor
    tcp: torch.Tensor  # (N, 3) tool centre point
    tcp_pose: torch.Tensor  # (N, 7) its pose (p, wxyz): the grasp link's orientation
    opening_dirs: torch.Tensor  # (N, 2, 3) each finger's opening direction
    speed: torch.Tensor
    angular_speed: torch.Tensor
    nontarget_force: torch.Tensor  # largest contact force on a robot link from anything but the target
    airframe_force: torch.Tensor
    gripper_opening: torch.Tensor
    tilt: torch.Tensor
    altitude: torch.Tensor  # airframe centre above the workspace floor
    tilt_rate: torch.Tensor  # roll-pitch angular speed
    clearance: torch.Tensor  # airframe proxy points from the scene's boxes, less the proxy radius
    fail_tilt: torch.Tensor
    fail_low: torch.Tensor
    fail_high: torch.Tensor
    fail_workspace: torch.Tensor
    proprio: torch.Tensor  # the policy-facing proprioceptive state (`observations.proprio_state`)
    object_rotation: torch.Tensor | None = None  # (N, 3, 3)
    grasp_point: torch.Tensor | None = None  # (N, 3) world position of the object's planned grasp point
    is_grasped: torch.Tensor | None = None  # both fingers >= GRASP_FORCE_N along their opening directions
    is_grasp_held: torch.Tensor | None = None  # both fingers > HELD_FORCE_N (spec's transport criterion)
    is_supported: torch.Tensor | None = None  # something other than the fingers carries >= 30% of its weight
    is_upright: torch.Tensor | None = None
    grasp_forces: torch.Tensor | None = None  # (N, 2) each finger's force from the object
    object_speed: torch.Tensor | None = None
    tcp_to_grasp_point: torch.Tensor | None = None
    object_displacement: torch.Tensor | None = None  # since the episode started (spec "Failure Analysis")
    object_turn: torch.Tensor | None = None  # ... the angle it turned
    grasp_streak: torch.Tensor | None = None  # control steps grasped in a row (a held start: confirmed from step 0)

    def flat(self) -> tuple[torch.Tensor, ...]:
        return tuple(t for t in self if t is not None)

    @classmethod
    def from_flat(cls, tensors) -> SharedSignals:
        return cls(*tensors)


def planned_grasp_point(position: torch.Tensor, R: torch.Tensor, tcp: torch.Tensor, grasp_point_local: torch.Tensor,
                        grasps_rim: torch.Tensor) -> torch.Tensor:
    """World position of the object's planned grasp point `(N, 3)`; for a rim grasp, the rim point nearest the tool
    centre point (a bowl turning about its axis in the jaws is still held where it was planned)."""
    g = grasp_point_local
    point = position + (R @ g[..., None])[..., 0]
    local = (R.transpose(-1, -2) @ (tcp - position)[..., None])[..., 0]
    direction = local[:, :2] / torch.linalg.norm(local[:, :2], dim=-1, keepdim=True).clamp_min(1e-6)
    rim = torch.cat([direction * g[:, :1], g[:, 2:3]], dim=-1)
    return torch.where(grasps_rim[:, None], position + (R @ rim[..., None])[..., 0], point)


def joint_parts(q: torch.Tensor, qd: torch.Tensor, virtual_joints: tuple[int, ...], finger_joints: tuple[int, int],
                arm_joints: tuple[int, ...]) -> tuple[AirframeState, torch.Tensor, torch.Tensor, tuple[torch.Tensor, ...]]:
    """The airframe state, the fingers' joint positions and velocities `(N, 2)` and the arm's `(q, qd)` (none on the
    gripper platform) from the articulation's whole joint vectors `(N, J)`."""
    virtual, fingers = joint_columns(virtual_joints, q.device), joint_columns(finger_joints, q.device)
    arm = joint_columns(arm_joints, q.device) if arm_joints else None
    arm_q = () if arm is None else (q[:, arm], qd[:, arm])
    return airframe_state_from_joints(q[:, virtual], qd[:, virtual]), q[:, fingers], qd[:, fingers], arm_q


def tool_centre_pose(grasp_link_pose: torch.Tensor, tcp_offset: tuple[float, float, float]) -> torch.Tensor:
    """The tool centre point's pose `(N, 7)` (p, wxyz) from the grasp link's: the offset is a pure translation in the
    link's frame, so the link's orientation is kept."""
    link_p, link_q = grasp_link_pose[:, :3], grasp_link_pose[:, 3:]
    offset = torch.tensor(tcp_offset, dtype=link_p.dtype, device=link_p.device)
    return torch.cat([link_p + quat_rotate(link_q, offset), link_q], -1)


def shared_signals(
    q: torch.Tensor,
    qd: torch.Tensor,
    grasp_link_pose: torch.Tensor,
    finger_quats: torch.Tensor,
    link_forces: torch.Tensor,
    finger_on_target: torch.Tensor,
    target_net: torch.Tensor,
    workspace_lo: torch.Tensor,
    workspace_hi: torch.Tensor,
    proxy_points: torch.Tensor,
    boxes: torch.Tensor,
    *target: torch.Tensor,
    const: SignalConstants,
) -> SharedSignals:
    """The step's shared signals from its reads.

    `q, qd` `(N, J)` the articulation's joint positions and velocities; `grasp_link_pose` `(N, 7)` (p, wxyz);
    `finger_quats` `(N, 2, 4)` the left and right finger links' orientations; the contact forces as in
    `ContactReadout`; the workspace box `(N, 3)` twice; the airframe's proxy points `(P, 3)` (body frame); the scene's
    boxes `(N, B, 8)` (`geometry.pack_boxes`). With a target object, `target` is its pose `(N, 7)`, linear velocity
    `(N, 3)`, planned grasp point in its frame `(N, 3)`, whether it is grasped at the rim `(N,)`, its mass `(N,)`,
    its pose at the episode's start (position `(N, 3)`, wxyz `(N, 4)`), and the grasp streak so far `(N,)`, whether
    the episode started with the object in the jaws `(N,)` and the episode's control step `(N,)`.
    """
    state, finger_q, finger_qd, arm_q = joint_parts(q, qd, const.virtual_joints, const.finger_joints, const.arm_joints)
    position, rotation = state.position, state.rotation
    tcp_pose = tool_centre_pose(grasp_link_pose, const.tcp_offset)
    tcp = tcp_pose[:, :3]
    e_y = torch.tensor([0.0, 1.0, 0.0], dtype=finger_quats.dtype, device=finger_quats.device)  # fingers close along y
    opening_dirs = torch.stack([quat_rotate(finger_quats[:, 0], e_y), -1.0 * quat_rotate(finger_quats[:, 1], e_y)], 1)
    omega_world = (rotation @ state.angular_velocity_body[..., None])[..., 0]
    envelope = flight_envelope_flags(position, rotation, workspace_lo, workspace_hi, const.safety)
    points = body_points_to_world(proxy_points, position, rotation)
    shared = dict(
        position=position,
        velocity=state.velocity,
        rotation=rotation,
        angular_velocity_body=state.angular_velocity_body,
        tcp=tcp,
        tcp_pose=tcp_pose,
        opening_dirs=opening_dirs,
        speed=torch.linalg.norm(state.velocity, dim=-1),
        angular_speed=torch.linalg.norm(omega_world, dim=-1),
        nontarget_force=nontarget_contact_force(link_forces, list(const.finger_idx), finger_on_target),
        airframe_force=torch.linalg.norm(link_forces[:, const.airframe_idx], dim=-1),
        gripper_opening=finger_q[:, 0] + finger_q[:, 1],
        tilt=tilt_angle(rotation),
        altitude=position[:, 2] - workspace_lo[:, 2],
        tilt_rate=torch.linalg.norm(state.angular_velocity_body[:, :2], dim=-1),
        clearance=min_distance_to_boxes(points, boxes) - const.proxy_radius,
        **envelope,
        proprio=proprio_state(state, finger_q, finger_qd, *arm_q),
    )
    if not const.has_target:
        return SharedSignals(**shared)
    pose, velocity, grasp_local, grasps_rim, mass, start_p, start_q, grasp_streak, starts_held, step = target
    p, q = pose[:, :3], pose[:, 3:]
    R = quat_wxyz_to_matrix(q)
    grasp_point = planned_grasp_point(p, R, tcp, grasp_local, grasps_rim)
    forces = torch.linalg.norm(finger_on_target, dim=-1)
    lift = support_force(target_net, finger_on_target)[:, 2]
    is_grasped = is_pinched(finger_on_target, opening_dirs, GRASP_FORCE_N)
    # an episode that starts holding the object (an eligible held state) starts with its grasp confirmed
    streak = consecutive(grasp_streak, is_grasped)
    held_start = starts_held & (step < GRASP_CONFIRM_STEPS)
    return SharedSignals(
        **shared,
        object_rotation=R,
        grasp_point=grasp_point,
        is_grasped=is_grasped,
        is_grasp_held=(forces > HELD_FORCE_N).all(-1),
        is_supported=lift >= SUPPORTED_WEIGHT_FRACTION * mass * GRAVITY_MPS2,
        is_upright=R[:, 2, 2] >= UPRIGHT_COS,
        grasp_forces=forces,
        object_speed=torch.linalg.norm(velocity, dim=-1),
        tcp_to_grasp_point=torch.linalg.norm(tcp - grasp_point, dim=-1),
        object_displacement=torch.linalg.norm(p - start_p, dim=-1),
        object_turn=2 * torch.acos(torch.clamp((q * start_q).sum(-1).abs(), max=1.0)),
        grasp_streak=torch.where(held_start, torch.clamp(streak, min=GRASP_CONFIRM_STEPS), streak),
    )


def _flat_signals(*tensors: torch.Tensor, const: SignalConstants) -> tuple[torch.Tensor, ...]:
    return shared_signals(*tensors, const=const).flat()


BOXES_INPUT = 10  # `shared_signals`' input position of the scene's boxes, whose count varies with the layout
TARGET_INPUT = BOXES_INPUT + 1  # ... and of the target object's pose (its velocity next)
_HERE = Path(__file__).resolve().parent
_SOURCES = [_HERE / "signals.py", _HERE / "checks.py", _HERE / "geometry.py", _HERE / "observations.py",
            _HERE / "control" / "so3.py", _HERE / "control" / "virtual_joints.py"]


def signals_kernel(const: SignalConstants, device: torch.device | str, compile: bool | None = None) -> Kernel:
    """The process's one `shared_signals` kernel for `const` on `device` (shared, so it compiles once per process and
    kind of env): call it with the tensors of `shared_signals`; `SharedSignals.from_flat` reads what it returns."""
    return shared_kernel(partial(_flat_signals, const=const), "shared_signals", const, _SOURCES, device, compile,
                         dynamic={BOXES_INPUT: 1})


class FlightSignalConstants(NamedTuple):
    """What `flight_signals` needs of the flight-test env besides tensors (hashable: a compiled kernel's key)."""

    tcp_offset: tuple[float, float, float]
    virtual_joints: tuple[int, ...]
    finger_joints: tuple[int, int]
    arm_joints: tuple[int, ...]


class FlightSignals(NamedTuple):
    """`(N, ...)` tensors: what the flight-test env (`AeroFly-v1`) reports and observes at a step."""

    altitude: torch.Tensor  # airframe centre height above the world origin
    tilt: torch.Tensor
    speed: torch.Tensor
    velocity: torch.Tensor  # (N, 3)
    proprio: torch.Tensor  # the policy-facing proprioceptive state (`observations.proprio_state`)
    tcp_pose: torch.Tensor  # (N, 7) p, wxyz


def flight_signals(q: torch.Tensor, qd: torch.Tensor, grasp_link_pose: torch.Tensor, *,
                   const: FlightSignalConstants) -> FlightSignals:
    """The flight-test env's signals from the articulation's joint vectors `(N, J)` and the grasp link's pose."""
    state, finger_q, finger_qd, arm_q = joint_parts(q, qd, const.virtual_joints, const.finger_joints, const.arm_joints)
    return FlightSignals(altitude=state.position[:, 2], tilt=tilt_angle(state.rotation),
                         speed=torch.linalg.norm(state.velocity, dim=-1), velocity=state.velocity,
                         proprio=proprio_state(state, finger_q, finger_qd, *arm_q),
                         tcp_pose=tool_centre_pose(grasp_link_pose, const.tcp_offset))


def _flat_flight_signals(*tensors: torch.Tensor, const: FlightSignalConstants) -> tuple[torch.Tensor, ...]:
    return tuple(flight_signals(*tensors, const=const))


def flight_signals_kernel(const: FlightSignalConstants, device: torch.device | str,
                          compile: bool | None = None) -> Kernel:
    """The process's one `flight_signals` kernel for `const` on `device`; `FlightSignals(*kernel(q, qd, pose))`."""
    return shared_kernel(partial(_flat_flight_signals, const=const), "flight_signals", const, _SOURCES, device, compile)
