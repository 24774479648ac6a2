"""Look first: the Pick expert turns on the spot until its object is ahead, then picks as it always does.

A skill episode starts at a random heading (spec: 0.5-1 m from the object), so most starts have the object behind
or beside the drone, outside all three cameras. The privileged expert flies straight at it anyway: it knows where
the object is. A camera policy cloned from that cannot: at the start its images do not say which way the expert
went, and it learns the average (a vision Pick policy parked 0.3 m from the object, docs/experiments.md). With
`look_first` the expert's first move is one a camera policy can copy: while the object is out of the front camera's
view it turns one fixed way (counter-clockwise) at a fixed rate, holding its position; once the object is in view it
turns towards it, slowing, until it is straight ahead (`LOOK_DONE_RAD`); then the skill's grasp heading is planned again from
the heading it now has (`PickEvaluator.plan_heading`, as at the skill's start) and the ordinary expert takes over.
What is demonstrated changes, not what is scored: starts, physics and success are the skill's own.
"""

from __future__ import annotations

import math

import torch

from ..envs.observations import wrap_angle
from .base import SkillExpert, tracking_velocity
from .motion import POSITION_GAIN, YAW_GAIN, flight_action

FRONT_HALF_FOV_RAD = math.radians(45.0)  # the front camera's 90 deg horizontal field of view (platforms.CameraMount)
IN_VIEW_RAD = FRONT_HALF_FOV_RAD - math.radians(10.0)  # in view with a margin: the object's own width
LOOK_DONE_RAD = math.radians(10.0)  # straight ahead: the pick takes over
BELOW_M = 0.25  # horizontally this close, the object is under the drone (the hand camera's view): nothing to turn to
LOOK_YAW_RATE_RPS = 0.8  # under the 1 rad/s limit: a turn in place at full rate sags the drone (pick.START_RISE_M)
HOLD_SPEED_MPS = 0.2  # the position hold while turning


def look_yaw_rate(bearing: torch.Tensor) -> torch.Tensor:
    """`(N,)` the yaw rate (rad/s) of the turn on the spot at the object's `bearing` `(N,)` (rad, left positive): one
    fixed way while the front camera cannot see it, so the choice never depends on what no camera shows; in view,
    towards it and slowing as it comes ahead, so that the pick's own turn starts from near rest (reversing a full-rate
    turn at once took the thrust from the rotors and dropped the drone 0.6 m into a counter)."""
    towards = torch.clamp(YAW_GAIN * bearing, -LOOK_YAW_RATE_RPS, LOOK_YAW_RATE_RPS)
    return torch.where(bearing.abs() < IN_VIEW_RAD, towards, torch.full_like(bearing, LOOK_YAW_RATE_RPS))


class LookFirst:
    """Wraps a Pick expert (`expert.pick.PickExpert`): the same interface, with a turn on the spot at each start."""

    def __init__(self, expert: SkillExpert):
        if expert.evaluator.skill != "pick":
            raise ValueError(f"--look-first turns to a Pick's object; the {expert.evaluator.skill} expert has none")
        self.expert = expert
        n, dev = expert.n, expert.device
        self.looking = torch.zeros(n, dtype=torch.bool, device=dev)
        self.hold = torch.zeros(n, 3, device=dev)  # where the airframe stays while it turns

    @property
    def phase(self) -> torch.Tensor:
        return self.expert.phase  # looking counts as the approach's start (PickPhase.APPROACH)

    def reset(self, env_idx: torch.Tensor) -> None:
        self.expert.reset(env_idx)
        self.looking[env_idx] = True
        self.hold[env_idx] = self.expert.state().position[env_idx]

    def bearing(self) -> tuple[torch.Tensor, torch.Tensor]:
        """`(N,)` the object's direction relative to the heading (rad, left positive) and horizontal distance (m)."""
        state = self.expert.state()
        to_object = self.expert.object_position()[:, :2] - state.position[:, :2]
        direction = torch.atan2(to_object[:, 1], to_object[:, 0])
        return wrap_angle(direction - state.yaw), torch.linalg.norm(to_object, dim=-1)

    def act(self) -> torch.Tensor:
        bearing, distance = self.bearing()
        done = self.looking & ((bearing.abs() < LOOK_DONE_RAD) | (distance < BELOW_M))
        if done.any():
            rows = done.nonzero()[:, 0]
            self.looking[rows] = False
            self.expert.evaluator.plan_heading(rows)  # the grasp heading from the heading it looks along now
            self.expert.reset(rows)
        action = self.expert.act()
        if not self.looking.any():
            return action
        yaw_rate = look_yaw_rate(bearing)
        position = self.expert.state().position
        velocity = tracking_velocity(position, self.hold, HOLD_SPEED_MPS, POSITION_GAIN)
        turning = flight_action(velocity, yaw_rate)
        action = action.clone()
        action[:, :4] = torch.where(self.looking[:, None], turning, action[:, :4])
        return action
