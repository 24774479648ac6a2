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

Its control step is one pure function of tensors (`pick_step`: transitions, targets, the action), so on a CPU it runs
as one compiled call (`kernels.Kernel`) instead of about 300 small ops; the planning at a reset stays in Python.
"""

from __future__ import annotations

import math
from enum import IntEnum
from functools import partial
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch

from ..accel import Kernel, shared_kernel
from ..envs.control.arm import arm_point_positions_body, normalized_arm_action
from ..envs.observations import heading_frame
from ..envs.platforms import MAX_SPEED_MPS
from ..envs.scenes.articulated import SUPPORT_EDGE_MARGIN_M
from ..envs.skills.pick import pick_grasp_target
from .base import SkillExpert, expert_action, goto_phase, tracking_velocity
from .motion import TURN_TOLERANCE_RAD, wrap_angle, yaw_rate_towards
from .planner import MIN_VERTICAL_CLEARANCE_M, START_SKIP_M, planner_for, route_at_some_heading
from .route import RouteFollower, route_target

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
        self._kernels: dict[bool, Kernel] = {}  # the compiled step by `routed`
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
        along = forward_of(self.heading)
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

    def _along(self, point: torch.Tensor) -> torch.Tensor:
        return along(point, forward_of(self.heading))

    def pre_grasp(self, grasp: torch.Tensor) -> torch.Tensor:
        env = self.env
        return pre_grasp_point(grasp, self.object_position()[:, 2], env.target_height, forward_of(self.heading),
                               env.target_grasps_rim, self.evaluator.enclosed, self.has_arm)

    def _draw_back(self) -> torch.Tensor:
        """`draw_back_m` of this step's object and this expert's plan."""
        support = self.evaluator.support_row
        return draw_back_m(support, self.heading, self.object_position(), forward_of(self.heading),
                           self.forearm_droops(self.evaluator))

    def _kernel(self) -> Kernel:
        """The compiled `pick_step` of this expert's law (whether it follows routes is part of it), found once per
        law: the lookup hashes the law's arm spec, a cost at every control step otherwise."""
        kernel = self._kernels.get(self.routed)
        if kernel is None:
            law = PickLaw(self.has_arm, self.routed, self.platform.arm, float(self.max_yaw_rate), float(self.yaw_gain))
            kernel = self._kernels[self.routed] = shared_kernel(partial(_flat_pick_step, law=law), "pick_expert", law,
                                                                _SOURCES, self.device)
        return kernel

    def step_inputs(self) -> list[torch.Tensor]:
        """This control step's tensors of `pick_step` (the env's step context and signals, the expert's memory, the
        plan)."""
        ctx, info, env, ev = self.env.current_step_context(), self.env.evaluate(), self.env, self.evaluator
        arm = (self.arm_rest, self.arm_top_down, self.arm_params.lower, self.arm_params.upper) if self.has_arm else ()
        return [
            ctx.state.position, ctx.state.velocity, ctx.state.rotation, ctx.tcp, ctx.object_pose.p, ctx.object_rotation,
            info["is_grasped"], info["lift_height"],
            self.phase, self.timer, self.retries, self.lift_from, self.draw_back, self.drawn, self.turned, self.route.index,
            ev.heading, ev.enclosed, ev.support_row, ev.clear_height(), env.target_height,
            env.target_grasp_point, env.target_half_extent, env.target_grasps_rim, self.align_tolerance, self.deepest,
            self.forearm_droops(ev), self.back_yaw, self.route.points, self.route.length, *arm,
        ]

    def act(self) -> torch.Tensor:
        step = PickStep(*self._kernel()(*self.step_inputs()))
        self.phase, self.timer, self.retries, self.lift_from = step.phase, step.timer, step.retries, step.lift_from
        self.draw_back, self.drawn, self.turned, self.route.index = step.draw_back, step.drawn, step.turned, step.route_index
        self.velocity_command = step.velocity
        return step.action


def forward_of(heading: torch.Tensor) -> torch.Tensor:
    """`(N, 3)` the horizontal unit vector of `heading`."""
    return torch.stack([torch.cos(heading), torch.sin(heading), torch.zeros_like(heading)], -1)


def along(point: torch.Tensor, forward: torch.Tensor) -> torch.Tensor:
    return (point * forward).sum(-1)


def entry_rise(object_z: torch.Tensor, height: torch.Tensor, grasp: torch.Tensor, grasps_rim: torch.Tensor,
               enclosed: torch.Tensor, has_arm: bool) -> torch.Tensor:
    """`(N,)` how far above the grasp the arm's fingers go into an enclosure (0 elsewhere)."""
    over_rim = object_z + height - grasp[:, 2] + ENTER_ABOVE_RIM_M
    rise = torch.where(grasps_rim, over_rim, torch.full_like(over_rim, ENTER_ABOVE_M))
    return torch.where(enclosed, rise, torch.zeros_like(rise)) if has_arm else torch.zeros_like(rise)


def pre_grasp_point(grasp: torch.Tensor, object_z: torch.Tensor, height: torch.Tensor, forward: torch.Tensor,
                    grasps_rim: torch.Tensor, enclosed: torch.Tensor, has_arm: bool) -> torch.Tensor:
    """`(N, 3)` where the tool centre point stops before the grasp: above the object, or (the arm reaching into an
    enclosure) `SIDE_STANDOFF_M` before the grasp along the heading, over the rim or the shelf board's edge."""
    top = object_z + height
    lift = (top - grasp[:, 2]).clamp_min(0.0) + ABOVE_OBJECT_M + 0.02  # finger tips sit 2 cm below the TCP
    above = grasp + torch.stack([torch.zeros_like(lift), torch.zeros_like(lift), lift], -1)
    if not has_arm:
        return above
    up = torch.zeros_like(grasp)
    up[:, 2] = entry_rise(object_z, height, grasp, grasps_rim, enclosed, has_arm)
    side = grasp - SIDE_STANDOFF_M * forward + up
    return torch.where((enclosed & has_arm)[:, None], side, above)


def draw_back_m(support: torch.Tensor, heading: torch.Tensor, object_p: torch.Tensor, forward: torch.Tensor,
                droops: torch.Tensor) -> torch.Tensor:
    """`(N,)` how far a reach-in draws the object towards the front before lifting it: `ENCLOSED_LIFT_BACK_M`, and
    for an object that droops the forearm no nearer than `DROOP_EDGE_KEEP_M` to the shelf board's front edge (the
    support's sampling area, a row of `env.supports`, stops `SUPPORT_EDGE_MARGIN_M` inside the board)."""
    relative = heading - support[:, 5]
    depth = (support[:, 2] * torch.cos(relative)).abs() + (support[:, 3] * torch.sin(relative)).abs()
    centre = support[:, 0] * torch.cos(heading) + support[:, 1] * torch.sin(heading)
    edge = centre - depth - SUPPORT_EDGE_MARGIN_M
    room = (along(object_p, forward) - edge - DROOP_EDGE_KEEP_M).clamp(0.0, ENCLOSED_LIFT_BACK_M)
    full = torch.full_like(room, ENCLOSED_LIFT_BACK_M)
    return torch.where(droops, room, full)


class PickLaw(NamedTuple):
    """What fixes `pick_step` besides its tensors (hashable: a compiled kernel's key)."""

    has_arm: bool
    routed: bool  # whether any env may follow a route
    arm: object  # the platform's ArmSpec (None: gripper)
    max_yaw_rate: float
    yaw_gain: float


class PickStep(NamedTuple):
    """The expert's memory after one control step, and its action."""

    phase: torch.Tensor
    timer: torch.Tensor
    retries: torch.Tensor
    lift_from: torch.Tensor
    draw_back: torch.Tensor
    drawn: torch.Tensor
    turned: torch.Tensor
    route_index: torch.Tensor
    velocity: torch.Tensor  # the commanded velocity (m/s)
    action: torch.Tensor


def pick_step(
    position, velocity, rotation, tcp, object_p, object_R, is_grasped, lift_height,
    phase, timer, retries, lift_from, draw_back, drawn, turned, route_index,
    heading, enclosed, support, clear_height, height, grasp_point, half_extent, grasps_rim, align_tolerance, deepest,
    droops, back_yaw, route_points, route_length, *arm: torch.Tensor, law: PickLaw,
) -> PickStep:
    """One control step of the pick expert as a pure function of tensors (`(N, ...)`; no branch on a tensor value):
    this step's airframe state, tool centre point, object pose and grasp signals, the expert's memory, and the
    episode's plan (`PickEvaluator`'s heading and support, the object's geometry, the route). `arm`: the arm
    platform's rest and top-down poses and joint limits."""
    P = PickPhase
    has_arm = law.has_arm
    yaw = torch.atan2(rotation[..., 1, 0], rotation[..., 0, 0])
    forward = forward_of(heading)
    grasp = pick_grasp_target(tcp, object_p, object_R, heading, enclosed, grasp_point, height, half_extent, grasps_rim,
                              law.arm)
    pre = pre_grasp_point(grasp, object_p[:, 2], height, forward, grasps_rim, enclosed, has_arm)
    speed = torch.linalg.norm(velocity, dim=-1)
    yaw_ok = wrap_angle(heading - yaw).abs() < YAW_TOLERANCE_RAD
    grasped = is_grasped
    reaches_in = enclosed & has_arm

    # transitions
    routing = phase == P.ROUTE
    if law.routed:
        waypoint, last, route_index = route_target(route_points, route_length, route_index, position)
        phase, timer, _ = goto_phase(phase, timer, P.ROUTE,
                                last & (torch.linalg.norm(waypoint - position, dim=-1) < ROUTE_ARRIVED_M), P.APPROACH)
    at_pre = torch.linalg.norm(tcp - pre, dim=-1) < 0.04
    phase, timer, _ = goto_phase(phase, timer, P.APPROACH, at_pre, P.ALIGN)
    aligned = (torch.linalg.norm((tcp - pre)[:, :2], dim=-1) < align_tolerance) & yaw_ok & (speed < SETTLED_MPS)
    phase, timer, _ = goto_phase(phase, timer, P.ALIGN, aligned, P.DESCEND)
    at_grasp = torch.linalg.norm(tcp - grasp, dim=-1) < AT_GRASP_M
    phase, timer, _ = goto_phase(phase, timer, P.DESCEND, at_grasp & (speed < SETTLED_MPS), P.CLOSE)
    confirmed = grasped & (timer >= GRASP_CONFIRM_STEPS)
    phase, timer, started_lift = goto_phase(phase, timer, P.CLOSE, confirmed, P.LIFT)
    lift_from = torch.where(started_lift[:, None], tcp, lift_from)
    draw_back = torch.where(started_lift, draw_back_m(support, heading, object_p, forward, droops), draw_back)
    drawn = drawn & ~started_lift
    failed_close = (phase == P.CLOSE) & (timer >= CLOSE_TIMEOUT_STEPS)
    lost = ((phase == P.LIFT) | (phase == P.HOLD)) & ~grasped & (timer > GRASP_CONFIRM_STEPS)
    retry = (failed_close | lost) & (retries < MAX_RETRIES)
    retries = retries + retry.long()
    phase = torch.where(retry, torch.full_like(phase, P.REOPEN), phase)
    timer = torch.where(retry, torch.zeros_like(timer), timer)
    lifted = lift_height >= 0.12
    phase, timer, _ = goto_phase(phase, timer, P.LIFT, lifted, P.HOLD)
    phase, timer, _ = goto_phase(phase, timer, P.REOPEN, timer >= 10, P.APPROACH)
    timer = timer + 1

    # commands per phase
    if has_arm:  # into an enclosure: above the grasp until over it, and no deeper than planned
        rise = entry_rise(object_p[:, 2], height, grasp, grasps_rim, enclosed, has_arm)
        away = torch.linalg.norm((tcp - grasp)[:, :2], dim=-1) > OVER_GRASP_M
        lifted_grasp = grasp + torch.stack([torch.zeros_like(rise), torch.zeros_like(rise), rise * away], -1)
        overreach = (along(lifted_grasp, forward) - deepest).clamp_min(0.0) * enclosed
        grasp = lifted_grasp - overreach[:, None] * forward
    target = torch.where((phase == P.APPROACH)[:, None] | (phase == P.ALIGN)[:, None] | (phase == P.REOPEN)[:, None], pre, grasp)
    headroom = clear_height - height - LIFT_HEADROOM_M
    lift = headroom.clamp(max=LIFT_HEIGHT_M)
    lift_target = lift_from + torch.stack([torch.zeros_like(lift), torch.zeros_like(lift), lift], -1)
    # Out of an enclosure the object is first drawn towards the front along the shelf, then lifted: the payload
    # 0.47 m ahead pitches the airframe nose-down as it comes off the shelf (the arm's feedforward covers the
    # arm's own weight only), and the drift that starts towards the fridge's front exceeds the disks' clearance.
    # An object that droops the forearm is drawn less where it stands near the front: the droop drags it further
    # back as it comes off the shelf, and a tomato soup can drawn the full 6 cm from 5 cm behind the edge swung
    # over the edge and below the shelf (the spec's object-drop failure while still held; 4 of 9).
    back = draw_back * reaches_in.float()
    drawn = drawn | ((phase == P.LIFT) & (along(tcp, forward) <= along(lift_from, forward) - back + 0.01))
    lift_target = lift_target - back[:, None] * forward
    lift_z = torch.where(reaches_in & ~drawn, lift_from[:, 2], lift_target[:, 2])
    lift_target = torch.cat([lift_target[:, :2], lift_z[:, None]], -1)
    target = torch.where((phase == P.LIFT)[:, None] | (phase == P.HOLD)[:, None], lift_target, target)
    # descend only while centred over the grasp: a drift pauses the descent until it is corrected
    drift = torch.linalg.norm((tcp - grasp)[:, :2], dim=-1) > align_tolerance
    hold_height = (phase == P.DESCEND) & drift & ~reaches_in
    target = torch.where(hold_height[:, None], torch.cat([grasp[:, :2], tcp[:, 2:]], -1), target)
    near = torch.linalg.norm(tcp - grasp, dim=-1) < FINAL_ZONE_M
    max_speed = torch.full_like(speed, APPROACH_SPEED_MPS)
    max_speed = torch.where(phase == P.ALIGN, torch.full_like(max_speed, 0.2), max_speed)
    max_speed = torch.where(phase == P.DESCEND, torch.where(near, FINAL_SPEED_MPS, DESCEND_SPEED_MPS), max_speed)
    max_speed = torch.where((phase == P.CLOSE) | (phase == P.HOLD), torch.full_like(max_speed, 0.1), max_speed)
    max_speed = torch.where(phase == P.LIFT, torch.full_like(max_speed, LIFT_SPEED_MPS), max_speed)
    max_speed = torch.where(phase == P.REOPEN, torch.full_like(max_speed, 0.1), max_speed)
    closed = (phase == P.CLOSE) | (phase == P.LIFT) | (phase == P.HOLD)
    gripper = torch.where(closed, torch.full_like(speed, -1.0), torch.ones_like(speed))
    fine = (phase == P.ALIGN) | (phase == P.DESCEND) | (phase == P.CLOSE)
    gain = torch.where(fine, FINE_GAIN, 1.2)
    point, yaw_target = tcp, heading
    if law.routed:  # on the route the airframe is driven to the waypoints
        target = torch.where(routing[:, None], waypoint, target)
        max_speed = torch.where(routing, torch.full_like(max_speed, ROUTE_SPEED_MPS), max_speed)
        point = torch.where(routing[:, None], position, tcp)
        backed_off = route_index > 0
        yaw_target = torch.where(routing & ~backed_off, back_yaw, yaw_target)
        turned = turned | (backed_off & (wrap_angle(heading - yaw).abs() < TURN_TOLERANCE_RAD))
        turning = routing & backed_off & ~turned
        target = torch.where(turning[:, None], route_points[:, 0], target)
    velocity_cmd = tracking_velocity(point, target, max_speed.clamp(max=MAX_SPEED_MPS), gain)
    yaw_rate = yaw_rate_towards(yaw, yaw_target, law.max_yaw_rate, law.yaw_gain)
    arm_action = None
    if has_arm:
        rest, top_down, lower, upper = arm
        arm_action = normalized_arm_action(torch.where(reaches_in[:, None], rest, top_down), lower, upper)
    action = expert_action(velocity_cmd, yaw_rate, gripper, arm_action)
    return PickStep(phase, timer, retries, lift_from, draw_back, drawn, turned, route_index, velocity_cmd, action)


def _flat_pick_step(*tensors: torch.Tensor, law: PickLaw) -> tuple[torch.Tensor, ...]:
    return tuple(pick_step(*tensors, law=law))


_HERE = Path(__file__).resolve().parent
_ENVS = _HERE.parent / "envs"
# every module `pick_step` reads code or constants from: a change to any of them is a new compiled package
_SOURCES = [_HERE / "pick.py", _HERE / "base.py", _HERE / "motion.py", _HERE / "route.py", _ENVS / "skills" / "pick.py",
            _ENVS / "observations.py", _ENVS / "platforms.py", _ENVS / "control" / "arm.py", _ENVS / "control" / "so3.py",
            _ENVS / "scenes" / "articulated.py"]
