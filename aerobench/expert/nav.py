"""Nav expert: follow a planned collision-free route to the target, then settle on it."""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
import torch

from ..envs.skills.nav import NAV_REACH_M
from .base import SkillExpert
from .motion import TURN_TOLERANCE_RAD, wrap_angle
from .planner import can_turn_in_place, planner_for, route_at_some_heading
from .route import RouteFollower

CRUISE_SPEED_MPS = 0.5
ARRIVE_SPEED_MPS = 0.2
ARRIVE_ZONE_M = 0.4
# While carrying, the velocity command ramps at this rate instead of stepping to cruise speed: the step tilted the
# drone 6 deg within 0.15 s and tore rim-pinched bowls out of the jaws at the start of 6 of 7 failed transports
# (docs/expert.md). 0.5 m/s^2 reaches cruise speed in 1 s.
CARRY_ACCEL_MPS2 = 0.5
# After a pick from inside a fixture (a fridge shelf) the arm and the object are still inside it: the route starts by
# backing straight out along the heading, this far, before the planner's route (which turns nowhere inside).
BACK_OUT_M = 0.45
# The heading is held while flying (the planner checks the footprint at it). When no route exists at the current
# heading (an arm 0.47 m long pointing into a fridge), the expert turns in place to the first of these that has one:
# towards the goal, then the current heading's quarter turns, then the room axes (furniture and its goals are
# aligned with the walls: a tall box hanging over an open drawer fits beside the counter only square to it); the turn
# itself must keep the footprint clear of the scene.
ROOM_AXES = [0.0, math.pi / 2, math.pi, -math.pi / 2]
ARM_FOLDED_RAD = 0.15  # every arm joint this close to the carry pose: folded
# A heavy object at the end of a level forearm needs more than the elbow's 0.9 N m (spec arm table): with the
# arm's fingers and palm, a 0.37 kg can held from the side asks about 1.2 N m, so the forearm droops until the moment
# is within the limit (0.6 rad in the carry pose) and never reaches the carry pose. An elbow that has come to rest
# below its target counts as folded; the route is then planned again for where the arm really hangs.
ARM_AT_REST_RADPS = 0.05
# A chain's transport ends 0.5 m above the place's anchor whatever hangs from the gripper: a tall box (the sugar box,
# 13.5 cm under the arm's grasp point) can stand on the counter's edge there, leaving no clear descent to the goal and
# no route at all (the expert then flew straight into a wall). Where the goal is blocked the route ends a little
# higher, still within the nav's reach of the target.
GOAL_LIFTS_M = (0.0, 0.3 * NAV_REACH_M, 0.6 * NAV_REACH_M)


class NavPhase(IntEnum):
    FLY = 0
    SETTLE = 1


class NavExpert(SkillExpert):
    """`carrying_depth`: how far a held object hangs below the gripper (for the planner's clearance; measured at reset,
    this nominal depth at least); `after_pick`:
    the evaluator of the pick this stage follows (its `enclosed` envs back out first)."""

    def __init__(self, env, evaluator, carrying_depth: float = 0.0, after_pick=None):
        super().__init__(env, evaluator)
        self.after_pick = after_pick
        self.route = RouteFollower(self.n, self.device)
        self.carrying_depth = carrying_depth
        self.depth = torch.full((self.n,), carrying_depth, device=self.device)  # per env, measured at reset
        self.heading = torch.zeros(self.n, device=self.device)  # held while flying the route
        self.start_yaw = torch.zeros(self.n, device=self.device)  # held while backing out
        self.turn_at = torch.zeros(self.n, 3, device=self.device)  # where the route starts (after backing out)
        self.backing = torch.zeros(self.n, dtype=torch.bool, device=self.device)
        self.turned = torch.ones(self.n, dtype=torch.bool, device=self.device)
        self.planned = torch.ones(self.n, dtype=torch.bool, device=self.device)
        # the arm platform flies with its arm folded (`ArmSpec.carry_pose_rad`; after a top-down pick, in the top-down
        # pose it holds the object in); it folds where the route starts
        self.carry_pose = self.arm_carry.expand(self.n, 3).clone() if self.has_arm else None
        self.folded = torch.zeros(self.n, dtype=torch.bool, device=self.device)  # latched once the arm has folded
        # a heavy object is carried with the forearm turned down (`held_arm_pose`): it hangs lower and nearer than the
        # planner assumed at reset, so the route is planned again once the arm has folded
        self.held_low = torch.zeros(self.n, dtype=torch.bool, device=self.device)

    def reset(self, env_idx):
        super().reset(env_idx)
        if self.carrying_depth > 0:
            self.depth[env_idx] = self.held_depth(env_idx)
        state = self.state()
        self.start_yaw[env_idx] = state.yaw[env_idx]
        self.velocity_command[env_idx] = state.velocity[env_idx]  # a ramp starts from how the drone moves now
        yaw = state.yaw
        if self.has_arm and self.after_pick is not None:
            level = self.carry_arm_pose(self.after_pick)
            self.carry_pose[env_idx] = self.held_arm_pose(level)[env_idx]
            self.held_low[env_idx] = (self.carry_pose != level).any(-1)[env_idx]
        self.folded[env_idx] = False
        back = BACK_OUT_M * torch.stack([torch.cos(yaw), torch.sin(yaw), torch.zeros_like(yaw)], -1)
        for i in env_idx.tolist():
            goal = self.evaluator.target[i].cpu().numpy()
            backing = self.after_pick is not None and bool(self.after_pick.enclosed[i])
            start = state.position[i] - back[i] if backing else state.position[i]
            # the heading is held while flying, so the planner checks the drone's real footprint at it (the
            # any-heading disk misses doorways and starts beside walls, leaving no route)
            heading, route = self._plan(i, start.cpu().numpy(), goal, float(yaw[i]))
            self.planned[i] = route is not None
            self.heading[i], self.turn_at[i], self.backing[i] = heading, start, backing
            self.turned[i] = heading == float(yaw[i])
            self.route.set(i, ([start.cpu().numpy()] if backing else []) + list(route if route is not None else [goal]))

    def _plan(self, i: int, start: np.ndarray, goal: np.ndarray, heading: float) -> tuple[float, list | None]:
        """The current heading and its route, or else the first candidate heading with a route that the drone can
        also turn to in place at `start`; to the goal, or else to the first of `GOAL_LIFTS_M` above it that has one."""
        toward = math.atan2(goal[1] - start[1], goal[0] - start[0])
        candidates = [heading, toward] + [heading + k * math.pi / 2 for k in (1, -1, 2)] + ROOM_AXES
        planner_at = lambda h: self._planner(i, h)  # noqa: E731
        return route_at_some_heading(
            planner_at, start, [goal + np.array([0.0, 0.0, lift]) for lift in GOAL_LIFTS_M], candidates,
            lambda h: h == heading or can_turn_in_place(planner_at, start, heading, h),
        )

    def _planner(self, i: int, heading: float):
        arm_q = None if self.carry_pose is None else self.carry_pose[i]
        return planner_for(self.env, i, float(self.depth[i]), heading=heading, arm_q=arm_q)

    def act(self):
        state = self.state()
        target, last = self.route.target(state.position)
        # backing out (first waypoint) keeps the pick's heading; then the turn in place; then the route
        backing = self.backing & (self.route.index == 0)
        self.turned |= ~backing & (wrap_angle(self.heading - state.yaw).abs() < TURN_TOLERANCE_RAD)
        turning = ~backing & ~self.turned
        target = torch.where(turning[:, None], self.turn_at, target)
        distance = torch.linalg.norm(target - state.position, dim=-1)
        self.goto(NavPhase.FLY, last & ~turning & (distance < 0.03), NavPhase.SETTLE)
        self.advance_timer()
        speed = torch.where(last & (distance < ARRIVE_ZONE_M), ARRIVE_SPEED_MPS, CRUISE_SPEED_MPS)
        yaw = torch.where(backing, self.start_yaw, self.heading)
        gripper = torch.full((self.n,), -1.0 if self.carrying_depth > 0 else 1.0, device=self.device)
        arm = None
        if self.has_arm:  # folded once backed out (a hover, so the swing of the held object is over before flying)
            arm = torch.where(backing[:, None], self.arm_rest.expand(self.n, 3), self.carry_pose)
            newly = ~backing & ~self.folded & self._arm_folded()
            self.folded |= newly
            if newly.any():  # a re-planned route may start with another heading: targets as above, on the new route
                self._replan_held_low(newly.nonzero()[:, 0].tolist())
                target, _ = self.route.target(state.position)
                target = torch.where((~backing & ~self.turned)[:, None], self.turn_at, target)
                yaw = torch.where(backing, self.start_yaw, self.heading)
            target = torch.where((~backing & ~self.folded)[:, None], self.turn_at, target)
        return self.action(target, speed, yaw, gripper, tracked=state.position, arm_target=arm,
                           max_accel=CARRY_ACCEL_MPS2 if self.carrying_depth > 0 else None)

    def _arm_folded(self) -> torch.Tensor:
        """`(N,)` the arm is in its carry pose, or as near it as its servos hold the load (`ARM_AT_REST_RADPS`)."""
        error = self.env.agent.arm_qpos() - self.carry_pose
        near = error.abs() < ARM_FOLDED_RAD
        drooped = (error[:, 1] > 0) & (self.env.agent.arm_qvel().abs().max(-1).values < ARM_AT_REST_RADPS)
        return near[:, 0] & near[:, 2] & (near[:, 1] | drooped)  # positive pitch turns the forearm down

    def _replan_held_low(self, rows: list[int]) -> None:
        """For envs that carry the object with the forearm turned down (`held_arm_pose`): plan the route again from
        here, with the held object's depth measured in that pose."""
        rows = [i for i in rows if bool(self.held_low[i])]
        if not rows:
            return
        state = self.state()
        depth = self.held_depth(torch.tensor(rows, device=self.device))
        for k, i in enumerate(rows):
            self.depth[i] = depth[k]
            start, goal = state.position[i].cpu().numpy(), self.evaluator.target[i].cpu().numpy()
            heading, route = self._plan(i, start, goal, float(self.heading[i]))
            if route is None:  # nothing better than the reset's plan
                continue
            self.turned[i] = bool(self.turned[i]) and heading == float(self.heading[i])
            self.heading[i], self.turn_at[i], self.backing[i] = heading, state.position[i], False
            self.route.set(i, route)
