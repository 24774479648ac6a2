"""Arm-platform extras of the flight loop (spec appendix "Robot platforms": "Arm platform" and "Contact mode").

- The flight loop adds a feedforward torque cancelling the arm's weight moment about the airframe centre; the
  payload-aware controller adds the carried object's, at the grasp point (its estimate m_hat - m0: zero under the
  nominal controller and once the object is set down). Not in the spec, whose arm platform opens and closes; an object
  carried 0.24-0.47 m ahead of the centre otherwise pitches the airframe until the velocity integrator has absorbed its
  moment, and tips it back when the support takes the load (docs/expert.md, LongHorizonRearrangement).
- Arm joints are position servos with the spec's torque limits.
- Contact mode: while a handle is pinched the shoulder servo gives zero torque and the arm feedforward is off, so the
  arm acts as a strut; on release the shoulder stiffens again and the velocity integrator resets.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ..platforms import GRAVITY, ArmSpec, GripperSpec

SHOULDER, ELBOW, WRIST = 0, 1, 2


@dataclass(frozen=True)
class ArmParams:
    """Arm geometry, masses and servo gains as tensors."""

    spec: ArmSpec
    finger_mass_kg: float
    lower: torch.Tensor  # (3,) joint limits, rad
    upper: torch.Tensor
    torque_limit: torch.Tensor  # (3,) N m
    stiffness: torch.Tensor  # (3,)
    damping: torch.Tensor  # (3,)

    @classmethod
    def from_spec(cls, arm: ArmSpec, gripper: GripperSpec, device: torch.device | str = "cpu") -> ArmParams:
        def t(values):
            return torch.tensor(values, dtype=torch.float32, device=device)

        return cls(
            spec=arm,
            finger_mass_kg=gripper.finger_mass_kg,
            lower=t([j.lower_rad for j in arm.joints]),
            upper=t([j.upper_rad for j in arm.joints]),
            torque_limit=t([j.torque_limit_nm for j in arm.joints]),
            stiffness=t([j.stiffness_nmprad for j in arm.joints]),
            damping=t([j.damping_nmsprad for j in arm.joints]),
        )


def arm_point_positions_body(q_arm: torch.Tensor, arm: ArmSpec) -> dict[str, torch.Tensor]:
    """Body-frame positions `(N, 3)` of the shoulder, elbow, wrist and grasp point for arm joints `q_arm` `(N, 3)`.

    Pitch joints turn about body +y (positive angle points the arm down); wrist roll turns about the forearm and
    moves none of these points.
    """
    shoulder = torch.tensor(arm.shoulder_position_m, dtype=q_arm.dtype, device=q_arm.device).expand(q_arm.shape[0], 3)

    def direction(pitch: torch.Tensor) -> torch.Tensor:
        return torch.stack([torch.cos(pitch), torch.zeros_like(pitch), -torch.sin(pitch)], dim=-1)

    upper_dir = direction(q_arm[:, SHOULDER])
    fore_dir = direction(q_arm[:, SHOULDER] + q_arm[:, ELBOW])
    elbow = shoulder + arm.upper_arm_length_m * upper_dir
    wrist = elbow + arm.forearm_length_m * fore_dir
    grasp = wrist + arm.wrist_to_grasp_m * fore_dir
    return {"shoulder": shoulder, "elbow": elbow, "wrist": wrist, "grasp": grasp, "forearm_dir": fore_dir}


def arm_mass_points_body(q_arm: torch.Tensor, params: ArmParams) -> tuple[torch.Tensor, torch.Tensor]:
    """Lumped masses of the arm (servo, links, fingers) and their body-frame positions, `(K,)` and `(N, K, 3)`.

    Link centres of mass are at the link midpoints, the wrist/palm mass a third of the way to the grasp point and
    the fingers at three quarters, matching the geometry the agent builds.
    """
    arm = params.spec
    p = arm_point_positions_body(q_arm, arm)
    positions = torch.stack(
        [
            p["shoulder"],
            0.5 * (p["shoulder"] + p["elbow"]),
            0.5 * (p["elbow"] + p["wrist"]),
            p["wrist"] + (arm.wrist_to_grasp_m / 3) * p["forearm_dir"],
            p["wrist"] + (0.75 * arm.wrist_to_grasp_m) * p["forearm_dir"],
        ],
        dim=1,
    )
    masses = torch.tensor(
        [arm.shoulder_servo_mass_kg, arm.upper_arm_mass_kg, arm.forearm_mass_kg, arm.wrist_mass_kg, 2 * params.finger_mass_kg],
        dtype=q_arm.dtype,
        device=q_arm.device,
    )
    return masses, positions


def elbow_gravity_torque(q_arm: torch.Tensor, params: ArmParams, load_kg: torch.Tensor, gravity: float = GRAVITY) -> torch.Tensor:
    """Static elbow torque `(N,)` (N m; positive turns the forearm down) that holds the forearm, wrist, fingers and a
    load `(N,)` at the grasp point still in pose `q_arm` `(N, 3)` on a level airframe. Above the elbow's torque limit
    the forearm cannot hold the pose: it droops until the load's lever arm is short enough."""
    masses, r_body = arm_mass_points_body(q_arm, params)
    points = arm_point_positions_body(q_arm, params.spec)
    elbow_x = points["elbow"][:, :1]
    beyond = masses[2:]  # forearm, wrist and fingers (the shoulder servo and the upper arm sit behind the elbow)
    moment = (beyond * (r_body[:, 2:, 0] - elbow_x)).sum(-1) + load_kg * (points["grasp"][:, 0] - elbow_x[:, 0])
    return gravity * moment


def arm_weight_feedforward_body(
    R: torch.Tensor, q_arm: torch.Tensor, params: ArmParams, gravity: float = GRAVITY, payload_kg: torch.Tensor | None = None
) -> torch.Tensor:
    """Body torque cancelling the arm's weight moment about the airframe centre: -R^T sum_i (R r_i) x (-m_i g e_z);
    with `payload_kg` `(N,)`, a point mass at the grasp point too."""
    masses, r_body = arm_mass_points_body(q_arm, params)
    masses = masses.expand(r_body.shape[0], -1)
    if payload_kg is not None:
        grasp = arm_point_positions_body(q_arm, params.spec)["grasp"]
        masses = torch.cat([masses, payload_kg[:, None]], 1)
        r_body = torch.cat([r_body, grasp[:, None]], 1)
    r_world = (R[:, None] @ r_body[..., None])[..., 0]
    weight = torch.zeros_like(r_world)
    weight[..., 2] = -masses * gravity
    moment_world = torch.linalg.cross(r_world, weight).sum(1)
    return -(R.transpose(-1, -2) @ moment_world[..., None])[..., 0]


def arm_servo_torques(
    q_arm: torch.Tensor, qd_arm: torch.Tensor, target: torch.Tensor, params: ArmParams, contact_mode: torch.Tensor
) -> torch.Tensor:
    """Torque-limited PD position servos; the shoulder is limp (zero torque) in contact mode."""
    tau = params.stiffness * (target - q_arm) - params.damping * qd_arm
    tau = torch.maximum(torch.minimum(tau, params.torque_limit), -params.torque_limit)
    tau[:, SHOULDER] = torch.where(contact_mode, torch.zeros_like(tau[:, SHOULDER]), tau[:, SHOULDER])
    return tau


def normalized_arm_action(q_arm: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
    """The normalized arm action in [-1, 1] that commands joint targets `q_arm` within `[lower, upper]` (the inverse of
    the body controller's mapping of its action)."""
    return 2.0 * (q_arm - lower) / (upper - lower) - 1.0
