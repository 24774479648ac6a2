"""Per-episode failure diagnostics of the spec's appendix "Failure Analysis", from one trajectory's signals.

- Pick: the drone's speed at first finger contact; whether the object was knocked (moved more than 3 cm or turned
  more than 20 deg from its start before it was grasped) and whether the scene was hit while the object was still
  undisturbed; the object's rotation from its pre-pick orientation at the handoff (the pick's success step).
- Place: the drone's speed when the jaws open (the release event).
- Holding a grasp (transport): the first violation of the spec's hold check (both fingers above 0.1 N and the tool
  centre point within 6 cm of the planned grasp point) that lasts the terminating 4 steps, and its mechanism: a
  physical slip (a finger lost its force) or "pinched beyond 6 cm" (still pinched, but displaced in the jaws).

Every value is `None` when its event never happened (no contact, no handoff, no release, no loss).
"""

from __future__ import annotations

import math

import numpy as np

from .events import NONTARGET_CONTACT_N, Signals, first_streak, first_time, signal

KNOCK_DISPLACEMENT_M = 0.03  # spec Fig. "Pick mechanisms": moved more than 3 cm ...
KNOCK_ROTATION_RAD = math.radians(20.0)  # ... or rotated more than 20 deg before being grasped
FINGER_CONTACT_N = 0.01  # a finger touches the object (above the solver's force noise)
# spec Protocol: a grasp is maintained while both fingers exert more than 0.1 N (the env's `is_grasp_held`) and the
HOLD_RADIUS_M = 0.06  # tool centre point stays within 6 cm of the planned grasp point;
HOLD_MAX_VIOLATIONS = 4  # four consecutive violations terminate the transport
SLIP, PINCHED_BEYOND = "slip", "pinched beyond 6 cm"


def _has(signals: Signals, *keys: str) -> bool:
    return all(k in signals for k in keys)


def _at(values: np.ndarray, t: int | None) -> float | None:
    return None if t is None else float(values[t])


def pick_mechanisms(signals: Signals) -> dict[str, float | bool | None]:
    forces = np.maximum(signal(signals, "grasp_force_left"), signal(signals, "grasp_force_right"))
    speed = signal(signals, "speed")
    out: dict[str, float | bool | None] = {"speed_at_finger_contact_mps": _at(speed, first_time(forces > FINGER_CONTACT_N))}
    grasped = first_time(signal(signals, "is_grasped"))
    before = slice(0, len(speed) if grasped is None else grasped)
    disturbed = ((signal(signals, "object_displacement")[before] > KNOCK_DISPLACEMENT_M)
                 | (signal(signals, "object_rotation")[before] > KNOCK_ROTATION_RAD))
    undisturbed = np.cumsum(disturbed) == 0  # up to the first step the object was disturbed
    hit = signal(signals, "nontarget_contact_force")[before] >= NONTARGET_CONTACT_N
    out["knocked_object"] = bool(disturbed.any())
    out["hit_scene"] = bool((hit & undisturbed).any())
    rotation = _at(signal(signals, "object_rotation"), first_time(signal(signals, "success")))
    out["handoff_rotation_deg"] = None if rotation is None else math.degrees(rotation)
    return out


def grasp_loss(signals: Signals) -> dict[str, float | str | None]:
    """The first terminating violation of the hold check after the grasp was first held, and its mechanism."""
    pinched = signal(signals, "is_grasp_held").astype(bool)  # both fingers above the env's HELD_FORCE_N (0.1 N)
    held = pinched & (signal(signals, "tcp_to_grasp_point") <= HOLD_RADIUS_M)
    first_held = first_time(held)
    if first_held is None:
        return {"grasp_loss_step": None, "grasp_loss_mechanism": None}
    start = first_streak(~held[first_held:], HOLD_MAX_VIOLATIONS)
    if start is None:
        return {"grasp_loss_step": None, "grasp_loss_mechanism": None}
    t = first_held + start
    return {"grasp_loss_step": t, "grasp_loss_mechanism": PINCHED_BEYOND if pinched[t] else SLIP}


def failure_analysis(skill: str, signals: Signals) -> dict[str, float | int | bool | str | None]:
    """The diagnostics above that `skill`'s trajectory has signals for."""
    out: dict[str, float | int | bool | str | None] = {}
    if skill == "pick" and _has(signals, "grasp_force_left", "grasp_force_right", "speed", "is_grasped",
                                 "object_displacement", "object_rotation", "nontarget_contact_force", "success"):
        out.update(pick_mechanisms(signals))
    if skill == "place" and _has(signals, "is_released", "speed"):
        out["speed_at_release_mps"] = _at(signal(signals, "speed"), first_time(signal(signals, "is_released")))
    if skill == "nav" and _has(signals, "is_grasp_held", "tcp_to_grasp_point"):
        out.update(grasp_loss(signals))
    return out
