"""Pick expert: approach, align, descend (or reach in), close, wait for the grasp, lift, hold.

Gripper platform: the grasp is taken from above (the L-shaped approach of the spec's Fig. trajectory diversity:
fly over the object, then descend onto it). Arm platform: from above too, in the top-down pose (forearm down,
`ArmSpec.top_down_pose_rad`), except into an enclosure (a fridge shelf), where the fingers point forward and the
grasp is taken from the side at the object's grasp height, reaching in along the heading. Guards: a grasp that does
not close within its time, or is lost while lifting, reopens and retries from the pre-grasp point (at most
`MAX_RETRIES` times).
A pick that follows another chain stage (e.g. after opening the fridge, the fingers still at the door's handle) first
backs away from where that stage left it and follows a planned route to a staging point before the pre-grasp point
(ROUTE), because the straight line from a handle into the fridge sweeps the fingers across the open door. A pick
that starts an episode flies straight to the pre-grasp point unless that line would take the drone into the scene
(a start behind a counter's upstand, the hanging fingers below its top edge); then it follows a planned route too,
from where it is.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
import torch

from ..envs.control.arm import arm_point_positions_body
from ..envs.observations import heading_frame
from ..envs.platforms import MAX_SPEED_MPS
from ..envs.scenes.articulated import SUPPORT_EDGE_MARGIN_M
from .base import SkillExpert
from .motion import TURN_TOLERANCE_RAD, wrap_angle
from .planner import MIN_VERTICAL_CLEARANCE_M, START_SKIP_M, planner_for, route_at_some_heading
from .route import RouteFollower

APPROACH_SPEED_MPS = 0.5
ALIGN_TOLERANCE_M = 0.012  # at most; wide objects leave the open fingers only a few mm (master chef can: 4 mm)
YAW_TOLERANCE_RAD = math.radians(4.0)
SETTLED_MPS = 0.04
DESCEND_SPEED_MPS = 0.15
FINAL_SPEED_MPS = 0.05  # the last few centimetres (spec: the expert touches objects at ~0.01 m/s)
FINAL_ZONE_M = 0.05
AT_GRASP_M = 0.008
LIFT_SPEED_MPS = 0.15  # spec appendix: the expert's lift commands 0.15 m/s
LIFT_HEIGHT_M = 0.20
LIFT_HEADROOM_M = 0.04  # under a board above the support (a fridge shelf) the lift stops this far below it
GRASP_CONFIRM_STEPS = 4
CLOSE_TIMEOUT_STEPS = 40
ABOVE_OBJECT_M = 0.10  # pre-grasp: the finger tips this far above the object's top (gripper platform)
SIDE_STANDOFF_M = 0.15  # pre-grasp: the tool centre point this far back from the grasp point (arm platform)
MAX_RETRIES = 2
# Reaching into an enclosure (a fridge shelf) the arm's horizontal fingers go in above the grasp and come down onto it
# once over it: 2 cm up clears the shelf board's front edge (the pads reach 1.5 cm below the tool centre point); a
# bowl's rim grasp goes in over the rim (the near wall stands across the way in) and drops onto the wall.
ENTER_ABOVE_M = 0.02
ENTER_ABOVE_RIM_M = 0.03
OVER_GRASP_M = 0.01
ENCLOSED_LIFT_BACK_M = 0.06
# ... except that an object which droops the forearm (`SkillExpert.forearm_droops`) is dragged back towards the
# drone as the forearm droops: its centre is drawn no nearer than this to the shelf board's front edge.
DROOP_EDGE_KEEP_M = 0.02
ENCLOSED_OVERREACH_M = 0.01  # ... and never deeper than the grasp planned at the start (a pushed object is let go)
BACK_OFF_M = 0.45  # a pick after another stage first backs this far away, keeping its heading, then turns
STAGING_M = 0.30  # ... and its route ends this far before the pre-grasp point along the grasp heading, the arm
# still outside whatever holds the object (a fridge shelf): the planner needs the route's end clear of the scene.
# Where that point is not (an object on a counter against a wall, the grasp heading facing the wall: 0.3 m back is in
# it) a nearer one is tried; with no route at all the expert flew straight and hit the wall.
STAGING_TRIES_M = (STAGING_M, STAGING_M / 2, 0.0)
ROUTE_SPEED_MPS = 0.3
APPROACH_FIRST_DROP_M = 0.10  # a first-stage approach that descends drops about this far before it moves across
# ... and a first-stage pick whose straight approach is blocked climbs this far before it turns to the grasp heading:
# a fast turn in place takes thrust from the rotors and sags the drone (10 cm beside a counter's upstand at the start)
START_RISE_M = 0.20
# after backing off, the pick turns to the grasp heading in place (within TURN_TOLERANCE_RAD) before its route
ROUTE_ARRIVED_M = 0.05
FINE_GAIN = 1.2  # 1/s: higher gains make the position loop ring against the velocity loop lag (2.5 diverges)


class PickPhase(IntEnum):
    APPROACH = 0
    ALIGN = 1
    DESCEND = 2
    CLOSE = 3
    LIFT = 4
    HOLD = 5
    REOPEN = 6
    ROUTE = 7  # back off, then follow the planned route to the staging point (a pick after another stage)


class PickExpert(SkillExpert):
    """The grasp heading and grasp point are the evaluator's (planned when the skill starts; `skills.pick`), the same
    ones the task state shows a learned policy."""

    def __init__(self, env, evaluator, after_stage: bool = False):
        super().__init__(env, evaluator)
        self.after_stage = after_stage
        self.route = RouteFollower(self.n, self.device)
        self.routed = after_stage  # whether any env may follow a route (the first-stage pick: only a blocked start)
        self.back_yaw = torch.zeros(self.n, device=self.device)  # the heading kept while backing off
        self.turned = torch.zeros(self.n, dtype=torch.bool, device=self.device)  # turned to the grasp heading after it
        self.align_tolerance = (env.grasp_side_room - 0.002).clamp(0.002, ALIGN_TOLERANCE_M)
        self.lift_from = torch.zeros(self.n, 3, device=self.device)
        self.retries = torch.zeros(self.n, dtype=torch.long, device=self.device)
        self.drawn = torch.zeros(self.n, dtype=torch.bool, device=self.device)  # enclosed: drawn to the front
        self.draw_back = torch.full((self.n,), ENCLOSED_LIFT_BACK_M, device=self.device)  # ... this far (m)
        self.deepest = torch.zeros(self.n, device=self.device)  # enclosed: along the heading, the deepest target

    def reset(self, env_idx):
        super().reset(env_idx)
        self.retries[env_idx] = 0
        self.deepest[env_idx] = self._along(self.grasp_point())[env_idx] + ENCLOSED_OVERREACH_M
        if self.after_stage:
            self._plan_route(env_idx)
            return
        blocked, rise = self._blocked_starts(env_idx)
        if blocked:
            self.routed = True
            self._plan_route(torch.tensor(blocked, device=self.device), first_move=rise)

    def _tcp_offset_at_heading(self) -> torch.Tensor:
        """`(N, 3)` the tool centre point's offset from the airframe once turned to the grasp heading (with the arm,
        in the pose it picks in)."""
        if self.has_arm:
            body = arm_point_positions_body(self.pick_arm_pose(self.evaluator), self.platform.arm)["grasp"]
            return heading_frame(body, -self.heading)
        state = self.state()
        return heading_frame(self.tcp() - state.position, state.yaw - self.heading)

    def _blocked_starts(self, env_idx: torch.Tensor) -> tuple[list[int], torch.Tensor]:
        """The envs of `env_idx` whose straight flight from the start to the pre-grasp point (at the start heading or
        at the grasp heading) would come within `MIN_VERTICAL_CLEARANCE_M` of the scene, and each one's first move
        `(M, 3)`: `START_RISE_M` up where there is room above (a shelf overhead: none, it turns where it is). The
        flight is not quite straight where it descends: thrust drops the drone at once while tilting into the
        horizontal motion takes a few steps (about 10 cm down before it has moved 3 cm across), so that first drop is
        checked too."""
        state = self.state()
        positions = state.position.cpu().numpy()
        goals = (self.pre_grasp(self.grasp_point()) - self._tcp_offset_at_heading()).cpu().numpy()
        arm_q = self.pick_arm_pose(self.evaluator) if self.has_arm else None
        blocked, rises = [], []
        for i in env_idx.tolist():
            start, goal = positions[i], goals[i]
            drop = start.copy()
            drop[2] -= min(APPROACH_FIRST_DROP_M, max(0.0, float(start[2] - goal[2])))
            if all(planner.segment_free(start, goal, START_SKIP_M, MIN_VERTICAL_CLEARANCE_M)
                   and planner.segment_free(start, drop, 0.0, MIN_VERTICAL_CLEARANCE_M)
                   for planner in (planner_for(self.env, i, heading=float(h), arm_q=None if arm_q is None else arm_q[i])
                                   for h in (state.yaw[i], self.heading[i]))):
                continue
            above = start + np.array([0.0, 0.0, START_RISE_M])
            # checked from START_SKIP_M up: the hanging fingers may start within a few cm of what blocks the approach
            room = planner_for(self.env, i, heading=float(state.yaw[i])).segment_free(start, above, START_SKIP_M,
                                                                                      MIN_VERTICAL_CLEARANCE_M)
            blocked.append(i)
            rises.append([0.0, 0.0, START_RISE_M if room else 0.0])
        return blocked, torch.tensor(rises, dtype=torch.float32, device=self.device).reshape(-1, 3)

    def _plan_route(self, env_idx: torch.Tensor, first_move: torch.Tensor | None = None) -> None:
        """Airframe waypoints: a first move keeping the current heading (`first_move` `(M, 3)`; default straight back
        `BACK_OFF_M` along it), then, turned to the grasp heading, the planner's route to a staging point
        `STAGING_M` (or the first of `STAGING_TRIES_M` with a route) before the pre-grasp point along the grasp
        heading (APPROACH flies the rest straight)."""
        state = self.state()
        along = self._forward()
        at_pre_grasp = self.pre_grasp(self.grasp_point()) - self._tcp_offset_at_heading()
        if first_move is None:
            yaw = state.yaw[env_idx]
            first_move = -torch.stack([torch.cos(yaw), torch.sin(yaw), torch.zeros_like(yaw)], -1) * BACK_OFF_M
        self.back_yaw[env_idx] = state.yaw[env_idx]
        self.turned[env_idx] = False
        for row, i in enumerate(env_idx.tolist()):
            start = (state.position[i] + first_move[row]).cpu().numpy()
            arm_q = self.pick_arm_pose(self.evaluator)[i] if self.has_arm else None
            heading = float(self.heading[i])
            stagings = [(at_pre_grasp[i] - distance * along[i]).cpu().numpy() for distance in STAGING_TRIES_M]
            _, route = route_at_some_heading(
                lambda h, i=i, arm_q=arm_q: planner_for(self.env, i, heading=h, arm_q=arm_q), start, stagings, [heading], lambda h: True
            )
            self.route.set(i, [start] + (route if route is not None else [stagings[-1]]))
        self.phase[env_idx] = PickPhase.ROUTE

    @property
    def heading(self) -> torch.Tensor:
        return self.evaluator.heading

    def grasp_point(self) -> torch.Tensor:
        ctx = self.env.current_step_context()
        return self.evaluator.grasp_target(ctx.tcp, ctx.object_pose, ctx.object_rotation)

    def _forward(self) -> torch.Tensor:
        return torch.stack([torch.cos(self.heading), torch.sin(self.heading), torch.zeros_like(self.heading)], -1)

    def _along(self, point: torch.Tensor) -> torch.Tensor:
        return (point * self._forward()).sum(-1)

    def entry_rise(self, grasp: torch.Tensor) -> torch.Tensor:
        """`(N,)` how far above the grasp the arm's fingers go into an enclosure (0 elsewhere)."""
        env = self.env
        over_rim = self.object_position()[:, 2] + env.target_height - grasp[:, 2] + ENTER_ABOVE_RIM_M
        rise = torch.where(env.target_grasps_rim, over_rim, torch.full_like(over_rim, ENTER_ABOVE_M))
        return torch.where(self.evaluator.enclosed, rise, torch.zeros_like(rise)) if self.has_arm else torch.zeros_like(rise)

    def pre_grasp(self, grasp: torch.Tensor) -> torch.Tensor:
        env = self.env
        top = self.object_position()[:, 2] + env.target_height
        lift = (top - grasp[:, 2]).clamp_min(0.0) + ABOVE_OBJECT_M + 0.02  # finger tips sit 2 cm below the TCP
        above = grasp + torch.stack([torch.zeros_like(lift), torch.zeros_like(lift), lift], -1)
        if not self.has_arm:
            return above
        up = torch.zeros_like(grasp)
        up[:, 2] = self.entry_rise(grasp)
        side = grasp - SIDE_STANDOFF_M * self._forward() + up
        return torch.where(self.reaches_in(self.evaluator)[:, None], side, above)

    def _draw_back(self) -> torch.Tensor:
        """`(N,)` how far a reach-in draws the object towards the front before lifting it: `ENCLOSED_LIFT_BACK_M`, and
        for an object that droops the forearm no nearer than `DROOP_EDGE_KEEP_M` to the shelf board's front edge
        (the support's sampling area stops `SUPPORT_EDGE_MARGIN_M` inside the board)."""
        support = self.env.supports[torch.arange(self.n, device=self.device), self.evaluator.support_index]
        relative = self.heading - support[:, 5]
        depth = (support[:, 2] * torch.cos(relative)).abs() + (support[:, 3] * torch.sin(relative)).abs()
        centre = support[:, 0] * torch.cos(self.heading) + support[:, 1] * torch.sin(self.heading)
        edge = centre - depth - SUPPORT_EDGE_MARGIN_M
        room = (self._along(self.object_position()) - edge - DROOP_EDGE_KEEP_M).clamp(0.0, ENCLOSED_LIFT_BACK_M)
        full = torch.full_like(room, ENCLOSED_LIFT_BACK_M)
        return torch.where(self.forearm_droops(self.evaluator), room, full)

    def act(self) -> torch.Tensor:
        P = PickPhase
        info = self.env.evaluate()
        state = self.state()
        tcp = self.tcp()
        grasp = self.grasp_point()
        pre = self.pre_grasp(grasp)
        speed = torch.linalg.norm(state.velocity, dim=-1)
        yaw_ok = wrap_angle(self.heading - state.yaw).abs() < YAW_TOLERANCE_RAD
        grasped = info["is_grasped"]

        # transitions
        routing = self.in_phase(P.ROUTE)
        if self.routed:
            waypoint, last = self.route.target(state.position)
            self.goto(P.ROUTE, last & (torch.linalg.norm(waypoint - state.position, dim=-1) < ROUTE_ARRIVED_M), P.APPROACH)
        at_pre = torch.linalg.norm(tcp - pre, dim=-1) < 0.04
        self.goto(P.APPROACH, at_pre, P.ALIGN)
        aligned = (torch.linalg.norm((tcp - pre)[:, :2], dim=-1) < self.align_tolerance) & yaw_ok & (speed < SETTLED_MPS)
        self.goto(P.ALIGN, aligned, P.DESCEND)
        at_grasp = torch.linalg.norm(tcp - grasp, dim=-1) < AT_GRASP_M
        self.goto(P.DESCEND, at_grasp & (speed < SETTLED_MPS), P.CLOSE)
        confirmed = grasped & (self.timer >= GRASP_CONFIRM_STEPS)
        started_lift = self.goto(P.CLOSE, confirmed, P.LIFT)
        self.lift_from = torch.where(started_lift[:, None], tcp, self.lift_from)
        self.draw_back = torch.where(started_lift, self._draw_back(), self.draw_back)
        self.drawn &= ~started_lift
        failed_close = self.in_phase(P.CLOSE) & (self.timer >= CLOSE_TIMEOUT_STEPS)
        lost = (self.in_phase(P.LIFT) | self.in_phase(P.HOLD)) & ~grasped & (self.timer > GRASP_CONFIRM_STEPS)
        retry = (failed_close | lost) & (self.retries < MAX_RETRIES)
        self.retries = self.retries + retry.long()
        self.phase = torch.where(retry, torch.full_like(self.phase, P.REOPEN), self.phase)
        self.timer = torch.where(retry, torch.zeros_like(self.timer), self.timer)
        lifted = info["lift_height"] >= 0.12
        self.goto(P.LIFT, lifted, P.HOLD)
        self.goto(P.REOPEN, self.timer >= 10, P.APPROACH)
        self.advance_timer()

        # commands per phase
        phase = self.phase
        if self.has_arm:  # into an enclosure: above the grasp until over it, and no deeper than planned
            rise = self.entry_rise(grasp)
            away = torch.linalg.norm((tcp - grasp)[:, :2], dim=-1) > OVER_GRASP_M
            lifted_grasp = grasp + torch.stack([torch.zeros_like(rise), torch.zeros_like(rise), rise * away], -1)
            overreach = (self._along(lifted_grasp) - self.deepest).clamp_min(0.0) * self.evaluator.enclosed
            grasp = lifted_grasp - overreach[:, None] * self._forward()
        target = torch.where((phase == P.APPROACH)[:, None] | (phase == P.ALIGN)[:, None] | (phase == P.REOPEN)[:, None], pre, grasp)
        headroom = self.evaluator.clear_height() - self.env.target_height - LIFT_HEADROOM_M
        lift = headroom.clamp(max=LIFT_HEIGHT_M)
        lift_target = self.lift_from + torch.stack([torch.zeros_like(lift), torch.zeros_like(lift), lift], -1)
        # Out of an enclosure the object is first drawn towards the front along the shelf, then lifted: the payload
        # 0.47 m ahead pitches the airframe nose-down as it comes off the shelf (the arm's feedforward covers the
        # arm's own weight only), and the drift that starts towards the fridge's front exceeds the disks' clearance.
        # An object that droops the forearm is drawn less where it stands near the front: the droop drags it further
        # back as it comes off the shelf, and a tomato soup can drawn the full 6 cm from 5 cm behind the edge swung
        # over the edge and below the shelf (the spec's object-drop failure while still held; 4 of 9).
        drawing = self.reaches_in(self.evaluator)
        back = self.draw_back * drawing.float()
        self.drawn |= (phase == P.LIFT) & (self._along(tcp) <= self._along(self.lift_from) - back + 0.01)
        lift_target = lift_target - back[:, None] * self._forward()
        lift_target[:, 2] = torch.where(drawing & ~self.drawn, self.lift_from[:, 2], lift_target[:, 2])
        target = torch.where((phase == P.LIFT)[:, None] | (phase == P.HOLD)[:, None], lift_target, target)
        # descend only while centred over the grasp: a drift pauses the descent until it is corrected
        drift = torch.linalg.norm((tcp - grasp)[:, :2], dim=-1) > self.align_tolerance
        hold_height = (phase == P.DESCEND) & drift & ~self.reaches_in(self.evaluator)
        target = torch.where(hold_height[:, None], torch.cat([grasp[:, :2], tcp[:, 2:]], -1), target)
        near = torch.linalg.norm(tcp - grasp, dim=-1) < FINAL_ZONE_M
        max_speed = torch.full((self.n,), APPROACH_SPEED_MPS, device=self.device)
        max_speed = torch.where(phase == P.ALIGN, torch.full_like(max_speed, 0.2), max_speed)
        max_speed = torch.where(phase == P.DESCEND, torch.where(near, FINAL_SPEED_MPS, DESCEND_SPEED_MPS), max_speed)
        max_speed = torch.where((phase == P.CLOSE) | (phase == P.HOLD), torch.full_like(max_speed, 0.1), max_speed)
        max_speed = torch.where(phase == P.LIFT, torch.full_like(max_speed, LIFT_SPEED_MPS), max_speed)
        max_speed = torch.where(phase == P.REOPEN, torch.full_like(max_speed, 0.1), max_speed)
        closed = (phase == P.CLOSE) | (phase == P.LIFT) | (phase == P.HOLD)
        gripper = torch.where(closed, torch.full((self.n,), -1.0, device=self.device), torch.ones(self.n, device=self.device))
        fine = (phase == P.ALIGN) | (phase == P.DESCEND) | (phase == P.CLOSE)
        gain = torch.where(fine, FINE_GAIN, 1.2)
        tracked, yaw = None, self.heading
        if self.routed:  # on the route the airframe is driven to the waypoints
            target = torch.where(routing[:, None], waypoint, target)
            max_speed = torch.where(routing, torch.full_like(max_speed, ROUTE_SPEED_MPS), max_speed)
            tracked = torch.where(routing[:, None], state.position, tcp)
            backed_off = self.route.index > 0
            yaw = torch.where(routing & ~backed_off, self.back_yaw, yaw)
            self.turned |= backed_off & (wrap_angle(self.heading - state.yaw).abs() < TURN_TOLERANCE_RAD)
            turning = routing & backed_off & ~self.turned
            target = torch.where(turning[:, None], self.route.points[:, 0], target)
        arm = self.pick_arm_pose(self.evaluator) if self.has_arm else None
        return self.action(target, max_speed.clamp(max=MAX_SPEED_MPS), yaw, gripper, arm_target=arm, gain=gain,
                           tracked=tracked)

