"""Checks every skill shares, one implementation each: grasp, support, flight envelope, collisions, failure latching.

Spec appendix "Trajectory Annotation and Outcome Categorization" names the failure causes; their thresholds where
the spec gives them (0.1 N finger contact for a maintained grasp, 0.27 m gripper clearance, 0.025 m/s platform
stability for 20 steps) live in the skill modules next to the check that uses them; the flight-envelope and
collision limits the spec leaves open are here, in `SafetyLimits`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from functools import partial
from pathlib import Path

import torch

from ..accel import Kernel, shared_kernel


class FailureCause(IntEnum):
    """Primary failure causes, named as in the spec's outcome tables."""

    NONE = 0
    COLLISION = 1
    COLLISION_FORCE = 2
    TILT = 3
    LOW = 4
    HIGH = 5
    WORKSPACE = 6
    OBJECT_DROP = 7
    UNSUPPORTED_RELEASE = 8
    AIRFRAME_CONTACT = 9  # Open/Close check N: success is no longer possible
    CLEARANCE = 10  # Open/Close check C
    PHASE = 11  # Open/Close: a phase failed (fail_insert, fail_pinch, fail_slip, fail_drive; see `phase`)

    @property
    def label(self) -> str:
        return _LABELS[self]


_LABELS = {
    FailureCause.NONE: "",
    FailureCause.COLLISION: "collision",
    FailureCause.COLLISION_FORCE: "fail_collision_force",
    FailureCause.TILT: "fail_tilt",
    FailureCause.LOW: "fail_low",
    FailureCause.HIGH: "fail_high",
    FailureCause.WORKSPACE: "fail_workspace",
    FailureCause.OBJECT_DROP: "fail_object_drop",
    FailureCause.UNSUPPORTED_RELEASE: "fail_unsupported_release",
    FailureCause.AIRFRAME_CONTACT: "airframe_contact",
    FailureCause.CLEARANCE: "clearance",
    FailureCause.PHASE: "phase_failure",
}


class Phase(IntEnum):
    """Open / Close execution phase, the spec's terminal execution phase p (tracked by `skills.articulation`)."""

    APPROACH = 0
    PINCH = 1
    DRIVE = 2
    RELEASE = 3
    RETRACT = 4
    DONE = 5
    FAIL_INSERT = 6
    FAIL_PINCH = 7
    FAIL_SLIP = 8
    FAIL_DRIVE = 9

    @property
    def label(self) -> str:
        return self.name.lower()

    @property
    def failed(self) -> bool:
        return self >= Phase.FAIL_INSERT


@dataclass(frozen=True)
class SafetyLimits:
    """Limits the spec leaves open (chosen here; documented in docs/skills.md)."""

    max_tilt_rad: float = math.radians(40.0)  # the arm platform needs 20-25 deg to pull a door; 40 deg is a crash
    min_altitude_m: float = 0.35  # airframe centre above the floor; the gripper's finger tips hang 0.30 m below it
    ceiling_margin_m: float = 0.15  # rotor disks (0.06 m above the centre) must stay under the ceiling
    collision_force_n: float = 1.0  # a UAV contact above this with anything but the target is a collision
    collision_impulse_budget_ns: float = 0.5  # Place: accumulated non-target contact impulse allowed (N s)
    drop_margin_m: float = 0.05  # object below its support (or the floor) by this much: dropped
    unsupported_release_steps: int = 5  # control steps without grasp and without support evidence


def flight_envelope_flags(
    position: torch.Tensor,
    rotation: torch.Tensor,
    workspace_lo: torch.Tensor,
    workspace_hi: torch.Tensor,
    limits: SafetyLimits,
) -> dict[str, torch.Tensor]:
    """fail_tilt / fail_low / fail_high / fail_workspace flags `(N,)` for the airframe centre and attitude."""
    tilt = torch.acos(torch.clamp(rotation[:, 2, 2], -1.0, 1.0))
    z = position[:, 2]
    return {
        "fail_tilt": tilt > limits.max_tilt_rad,
        "fail_low": z < workspace_lo[:, 2] + limits.min_altitude_m,
        "fail_high": z > workspace_hi[:, 2] - limits.ceiling_margin_m,
        "fail_workspace": ((position[:, :2] < workspace_lo[:, :2]) | (position[:, :2] > workspace_hi[:, :2])).any(-1),
    }


def is_pinched(
    finger_forces: torch.Tensor, opening_dirs: torch.Tensor, min_force: float, max_angle_deg: float = 85.0
) -> torch.Tensor:
    """Both fingers pushed open by the pinched thing with at least `min_force` N each, `(N,)`.

    `finger_forces` `(N, 2, 3)` are the forces on the fingers, `opening_dirs` `(N, 2, 3)` each finger's opening
    direction: a real pinch pushes each finger outwards, roughly along it.
    """
    magnitude = torch.linalg.norm(finger_forces, dim=-1)
    cos = (finger_forces * opening_dirs).sum(-1) / magnitude.clamp_min(1e-9)
    aligned = cos >= math.cos(math.radians(max_angle_deg))
    return ((magnitude >= min_force) & aligned).all(dim=-1)


def nontarget_contact_force(
    link_forces: torch.Tensor, finger_idx: list[int], finger_on_target: torch.Tensor
) -> torch.Tensor:
    """Largest contact force `(N,)` on any robot link from anything but the target object (fingers minus grasp)."""
    other = link_forces.clone()
    other[:, finger_idx] -= finger_on_target
    return torch.linalg.norm(other, dim=-1).max(dim=-1).values


def support_force(target_net: torch.Tensor, finger_on_target: torch.Tensor) -> torch.Tensor:
    """Contact force `(N, 3)` on the object from everything but the fingers (the fingers push the object with minus
    the force they feel)."""
    return target_net + finger_on_target.sum(dim=1)


def latch_failure(current: torch.Tensor, flags: list[tuple[FailureCause, torch.Tensor]]) -> torch.Tensor:
    """Keep an env's first failure cause; a newly failing env takes the first flagged cause in `flags` order."""
    new = torch.zeros_like(current)
    for cause, flag in reversed(flags):
        new = torch.where(flag, torch.full_like(new, int(cause)), new)
    return torch.where(current != 0, current, new)


def verdict(current: torch.Tensor, success: torch.Tensor, *flags: torch.Tensor,
            causes: tuple[int, ...]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """A control step's outcome `(N,)`: the latched failure cause (`latch_failure` of `flags`, flagging `causes` in
    that order), whether the env failed, its success (`success` where it has not failed) and ManiSkill's sparse
    reward of them (1 on success, -1 on failure, else 0)."""
    cause = latch_failure(current, list(zip(causes, flags)))
    fail = cause != 0
    success = success & ~fail
    return cause, fail, success, success.float() - fail.float()


def verdict_kernel(causes: tuple[int, ...], device: torch.device | str, compile: bool | None = None) -> Kernel:
    """The process's one `verdict` kernel for the flagged `causes` (in priority order) on `device`: about twenty
    small ops as one call on a CPU."""
    return shared_kernel(partial(verdict, causes=causes), "verdict", causes, [Path(__file__).resolve()], device, compile)


def consecutive(count: torch.Tensor, condition: torch.Tensor) -> torch.Tensor:
    """Run length of `condition` ending now (control steps)."""
    return torch.where(condition, count + 1, torch.zeros_like(count))


def first_time(first: torch.Tensor, event: torch.Tensor, step: torch.Tensor) -> torch.Tensor:
    """First control step at which `event` held (-1 while never); spec t_b = min{t : b_t = 1}."""
    return torch.where((first < 0) & event, step, first)
