"""Nav expert: follow a planned collision-free route to the target, then settle on it."""

from __future__ import annotations

from enum import IntEnum

import torch

from .base import SkillExpert
from .planner import planner_for
from .route import RouteFollower

CRUISE_SPEED_MPS = 0.5
ARRIVE_SPEED_MPS = 0.2
ARRIVE_ZONE_M = 0.4
# While carrying, the velocity command ramps at this rate instead of stepping to cruise speed: the step tilted the
# drone 6 deg within 0.15 s and tore rim-pinched bowls out of the jaws at the start of 6 of 7 failed transports
# (docs/expert.md). 0.5 m/s^2 reaches cruise speed in 1 s.
CARRY_ACCEL_MPS2 = 0.5


class NavPhase(IntEnum):
    FLY = 0
    SETTLE = 1


class NavExpert(SkillExpert):
    """`carrying_depth`: how far a held object hangs below the gripper (for the planner's clearance)."""

    def __init__(self, env, evaluator, carrying_depth: float = 0.0):
        super().__init__(env, evaluator)
        self.route = RouteFollower(self.n, self.device)
        self.carrying_depth = carrying_depth
        self.heading = torch.zeros(self.n, device=self.device)
        self.planned = torch.ones(self.n, dtype=torch.bool, device=self.device)

    def reset(self, env_idx):
        super().reset(env_idx)
        position = self.state().position
        self.heading[env_idx] = self.state().yaw[env_idx]
        self.velocity_command[env_idx] = self.state().velocity[env_idx]  # a ramp starts from how the drone moves now
        for i in env_idx.tolist():
            goal = self.evaluator.target[i].cpu().numpy()
            # the heading is held while flying, so the planner checks the drone's real footprint at it (the
            # any-heading disk misses doorways and starts beside walls, leaving no route)
            planner = planner_for(self.env, i, self.carrying_depth, heading=float(self.heading[i]))
            route = planner.plan(position[i].cpu().numpy(), goal)
            self.planned[i] = route is not None
            self.route.set(i, route if route is not None else [goal])

    def act(self):
        state = self.state()
        target, last = self.route.target(state.position)
        distance = torch.linalg.norm(target - state.position, dim=-1)
        self.goto(NavPhase.FLY, last & (distance < 0.03), NavPhase.SETTLE)
        self.advance_timer()
        speed = torch.where(last & (distance < ARRIVE_ZONE_M), ARRIVE_SPEED_MPS, CRUISE_SPEED_MPS)
        gripper = torch.full((self.n,), -1.0 if self.carrying_depth > 0 else 1.0, device=self.device)
        return self.action(target, speed, self.heading, gripper, tracked=state.position,
                           max_accel=CARRY_ACCEL_MPS2 if self.carrying_depth > 0 else None)
