"""PPO's rewards, defined once for every skill (spec, "PPO Training": task progress and success criteria, with
penalties for undesirable actions and contacts).

All terms read the env's per-step `info` (`AeroSkillEnv.evaluate()`), `(N,)` tensors:

    r = w_progress * (phi_t - phi_{t-1})                     progress: the change of a per-skill potential phi
      + w_success * success - w_fail * fail                  the skill's own success check; any latched failure
      - w_tilt * max(0, tilt - tilt_soft)                    attitude beyond a soft limit (hard limit: fail_tilt)
      - w_altitude * max(0, altitude_floor - altitude)       flying low (the hard limit ends the episode: fail_low)
      - w_contact * min(nontarget_force / collision_force, 1) touching anything but the target
      - w_action * |a|^2                                     large commands

Potentials (higher is closer to done); each is a sum of signals the skill's evaluator already computes:

| skill | phi |
| --- | --- |
| pick | -tcp_to_grasp_point + grasped + 2 lift / PICK_LIFT_M (lift only while grasped) |
| place | -goal_distance + support contact + released + gripper clear |
| nav | -nav_distance |
| open | -tcp_to_handle + handle pinched + 2 articulation_progress |
| close | -tcp_to_handle + handle pinched + 2 (1 - articulation_progress) |

Differences of a potential make progress hard to farm (leaving and coming back pays nothing net). This is Ng et al.'s
(1999) shaping with gamma = 1, not their discounted form gamma * phi_t - phi_{t-1}: under PPO's discount (0.97) it
is not guaranteed to keep the optimal policy unchanged (it penalises the discounted value of reaching a higher
potential slightly less than the invariant form). The committed PPO rows were trained with it, so it stays as is.

`kind="dense"` pays progress at every step instead, as ManiSkill's dense rewards do: the same potential with each
distance d mapped to closeness c(d) = (1 - tanh(d / 1 m) + 1 - tanh(d / 0.1 m)) / 2 in (0, 1] (a slope far away and
a steep one within centimetres), divided by its maximum, so a step earns up to `w_progress`. The success term is
then `w_progress / (1 - gamma)`, what staying in the best state forever is worth, so finishing never pays less than
hovering at the goal; a failure also forfeits the steps it cuts off. A sum of differences pays at most the distance
covered in all (under a metre), which the per-step penalties of a few hundred steps outweigh; the dense form pays
for being close at every step (docs/experiments.md, "PPO from scratch on a CPU").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ..envs.checks import SafetyLimits
from ..envs.skills.pick import PICK_LIFT_M

SAFETY = SafetyLimits()
REWARD_KINDS = ("potential", "dense")
DENSE_NEAR_M = 0.1  # the dense closeness's steep scale: centimetres matter at the grasp (a can's side room is 4 mm)


@dataclass(frozen=True)
class RewardWeights:
    progress: float = 1.0
    success: float = 10.0
    fail: float = 5.0
    tilt: float = 1.0  # per rad beyond `tilt_soft_rad`
    tilt_soft_rad: float = math.radians(20.0)  # half of the hard limit (SafetyLimits.max_tilt_rad, 40 deg)
    altitude: float = 1.0  # per m below `altitude_floor_m`
    altitude_floor_m: float = SAFETY.min_altitude_m + 0.15  # a soft band above the hard floor
    contact: float = 0.5
    action: float = 0.01


def _f(info: dict, key: str, skill: str) -> torch.Tensor:
    if key not in info:
        raise KeyError(f"the {skill} reward needs info[{key!r}], which the env did not report")
    return info[key].float()


def closeness(d: torch.Tensor) -> torch.Tensor:
    """(1 - tanh(d / 1 m) + 1 - tanh(d / 0.1 m)) / 2: 1 at the goal, a slope at a metre and a steep one at centimetres."""
    return 1.0 - 0.5 * (torch.tanh(d) + torch.tanh(d / DENSE_NEAR_M))


# Each skill's progress as (distance to its goal, milestones reached): phi = -distance + milestones.
def _pick(info, skill):
    grasped = _f(info, "is_grasped", skill)
    lift = _f(info, "lift_height", skill).clamp(0.0, PICK_LIFT_M) / PICK_LIFT_M
    return _f(info, "tcp_to_grasp_point", skill), grasped + 2.0 * lift * grasped


def _place(info, skill):
    return (_f(info, "goal_distance", skill), _f(info, "is_support_contact", skill) + _f(info, "is_released", skill)
            + _f(info, "is_gripper_clear", skill))


def _nav(info, skill):
    d = _f(info, "nav_distance", skill)
    return d, torch.zeros_like(d)


def _open(info, skill):
    return _f(info, "tcp_to_handle", skill), _f(info, "is_handle_pinched", skill) + 2.0 * _f(info, "articulation_progress", skill)


def _close(info, skill):
    progress = 1.0 - _f(info, "articulation_progress", skill)
    return _f(info, "tcp_to_handle", skill), _f(info, "is_handle_pinched", skill) + 2.0 * progress


PROGRESS = {"pick": _pick, "place": _place, "nav": _nav, "open": _open, "close": _close}
MILESTONES = {"pick": 3.0, "place": 3.0, "nav": 0.0, "open": 3.0, "close": 3.0}  # each skill's milestones at its goal


def _progress(skill: str, info: dict) -> tuple[torch.Tensor, torch.Tensor]:
    if skill not in PROGRESS:
        raise ValueError(f"no PPO reward for skill {skill!r}; valid: {', '.join(PROGRESS)}")
    return PROGRESS[skill](info, skill)


def potential(skill: str, info: dict) -> torch.Tensor:
    """phi `(N,)` of the table above."""
    distance, milestones = _progress(skill, info)
    return milestones - distance


def _dense(skill: str, distance: torch.Tensor, milestones: torch.Tensor) -> torch.Tensor:
    """The dense reward's progress `(N,)` in (0, 1]: phi with closeness for minus distance, over its goal value."""
    return (closeness(distance) + milestones) / (1.0 + MILESTONES[skill])


def reward(skill: str, info: dict, prev_potential: torch.Tensor, action: torch.Tensor,
           weights: RewardWeights = RewardWeights(), kind: str = "potential",
           gamma: float = 0.97) -> tuple[torch.Tensor, torch.Tensor, dict[str, torch.Tensor]]:
    """(reward `(N,)`, this step's potential (pass it back next step), the terms by name for logging). `kind`:
    "potential" (differences of phi, success `w_success`) or "dense" (progress at every step, success worth
    staying at the goal forever under `gamma`)."""
    if kind not in REWARD_KINDS:
        raise ValueError(f"unknown reward kind {kind!r}; valid: {', '.join(REWARD_KINDS)}")
    distance, milestones = _progress(skill, info)  # read once: the potential and the dense progress share them
    phi = milestones - distance
    w = weights
    dense = kind == "dense"
    terms = {
        "progress": w.progress * (_dense(skill, distance, milestones) if dense else phi - prev_potential),
        "success": (w.progress / (1.0 - gamma) if dense else w.success) * _f(info, "success", skill),
        "fail": -w.fail * _f(info, "fail", skill),
        "tilt": -w.tilt * (_f(info, "tilt", skill) - w.tilt_soft_rad).clamp_min(0.0),
        "altitude": -w.altitude * (w.altitude_floor_m - _f(info, "altitude", skill)).clamp_min(0.0),
        "contact": -w.contact * (_f(info, "nontarget_contact_force", skill) / SAFETY.collision_force_n).clamp(max=1.0),
        "action": -w.action * action.float().pow(2).sum(-1),
    }
    return sum(terms.values()), phi, terms
