"""Place expert: transport, align over the goal, descend to support contact, stop before release, open, retreat.

The object hangs in the jaws, so alignment and descent steer the object (not the tool centre point) onto the goal.
Release happens only once the support has carried the object for 9 control steps (the task state's set-down time,
which a policy reads too) and the drone has stopped (spec appendix: the expert's release speeds are a few mm/s);
while the fingers open the drone holds the release point (a position hold); the retreat is straight up past the
0.27 m clearance, then the drone hovers still.

Its control step is one pure function of tensors (`place_step`), run as one compiled call on a CPU
(`kernels.Kernel`); the route planning at a reset stays in Python.
"""

from __future__ import annotations

from enum import IntEnum
from functools import partial
from pathlib import Path
from typing import NamedTuple

import torch

from ..accel import Kernel, shared_kernel
from ..envs.control.arm import normalized_arm_action
from .base import SkillExpert, expert_action, goto_phase, tracking_velocity
from .motion import POSITION_GAIN, TURN_TOLERANCE_RAD, wrap_angle, yaw_rate_towards
from .planner import planner_for
from .route import RouteFollower, route_target

TRANSPORT_SPEED_MPS = 0.45
TRANSPORT_CLEARANCE_M = 0.15  # the object's bottom this far above the goal surface while transporting
ALIGN_TOLERANCE_M = 0.01
SETTLED_MPS = 0.03
DESCEND_SPEED_MPS = 0.10
TOUCH_SPEED_MPS = 0.04
TOUCH_ZONE_M = 0.04
PRESS_SPEED_MPS = 0.04  # on the surface: keep sinking gently until the support carries the object
SET_DOWN_STEPS = 3  # control steps of support contact before the drone stops pressing
STOPPED_MPS = 0.008  # "stop before release"
# The arm's fingertips reach 3 cm below its grasp point: a short object (the 33 mm tuna can) picked from a table is
# held with its bottom level with the tips, and on the support the tips carry the press while the object hangs a
# fraction of a millimetre above it (no support contact, no set-down). Stalled there (the object's bottom within
# STALL_HEIGHT_M of the goal, the drone stopped, both observable) for STALL_STEPS, the expert lets go.
STALL_HEIGHT_M = 0.001
STALL_STEPS = 15
STOPPED_STEPS = 6  # further control steps of support contact before the release
OPEN_STEPS = 12
HOLD_SPEED_MPS = 0.05  # while the fingers open: enough to pull a few mm of drift back, too slow to shove the object
RETREAT_HEIGHT_M = 0.40  # above the release point: beyond the 0.27 m clearance with margin
RETREAT_SPEED_MPS = 0.2
SIDE_BACK_OFF_M = 0.12  # after a side grasp the open hand backs off this far before it rises
SIDE_EASE_BACK_M = 0.02  # ... and eases back this far while the fingers open


class PlacePhase(IntEnum):
    TRANSPORT = 0
    ALIGN = 1
    DESCEND = 2
    STOP = 3
    OPEN = 4
    RETREAT = 5
    HOVER = 6


class PlaceExpert(SkillExpert):
    def __init__(self, env, evaluator):
        super().__init__(env, evaluator)
        self.pick = evaluator.after_pick  # the chain's pick evaluator that grasped the object (None: a Place start)
        self.heading = torch.zeros(self.n, device=self.device)
        self.release_point = torch.zeros(self.n, 3, device=self.device)
        self.stop_point = torch.zeros(self.n, 3, device=self.device)
        self.stall_steps = torch.zeros(self.n, dtype=torch.long, device=self.device)
        self.route = RouteFollower(self.n, self.device)
        self.planned = torch.ones(self.n, dtype=torch.bool, device=self.device)
        self._step_kernel: Kernel | None = None  # the compiled `place_step`, found at the first step
        # The arm platform places in the pose it carried the object in (`carry_arm_pose`): unfolding to the working
        # pose over a drawer swept the forearm into it.
        self.arm_pose = self.arm_rest.expand(self.n, 3).clone() if self.has_arm else None
        # ... or, with a heavy object, with the forearm turned down as it was carried (`held_arm_pose`) until the
        # support carries the object, then in the pose of the pick again (levelling it onto its base)
        self.level_pose = None if self.arm_pose is None else self.arm_pose.clone()
        self.levelling = torch.zeros(self.n, dtype=torch.bool, device=self.device)
        self.backed_off = torch.zeros(self.n, dtype=torch.bool, device=self.device)  # the side grasp's hand is clear
        # Where the env's place heading is not the one the place begins with (an arm platform's goal by a wall), the
        # drone first turns to it in place: carrying the object over the goal at the old heading stood the airframe
        # in the wall before the turn had come round (docs/expert.md, "The place's heading").
        self.turn_at = torch.zeros(self.n, 3, device=self.device)
        self.turned = torch.ones(self.n, dtype=torch.bool, device=self.device)

    def above_goal_tcp(self) -> torch.Tensor:
        """Tool-centre-point target of the transport: the held object's bottom over the goal, with clearance."""
        hang = self.tcp() - self.object_position()
        return self.evaluator.goal + torch.tensor([0.0, 0.0, TRANSPORT_CLEARANCE_M], device=self.device) + hang

    def reset(self, env_idx):
        super().reset(env_idx)
        self.stall_steps[env_idx] = 0
        self.levelling[env_idx] = False
        self.backed_off[env_idx] = False
        state = self.state()
        self.heading[env_idx] = self.evaluator.heading[env_idx]  # the env's place heading (a policy reads it too)
        self.turn_at[env_idx] = state.position[env_idx]
        self.turned[env_idx] = wrap_angle(self.heading - state.yaw)[env_idx].abs() < TURN_TOLERANCE_RAD
        if self.has_arm:
            self.level_pose[env_idx] = self.carry_arm_pose(self.pick)[env_idx]
            self.arm_pose[env_idx] = self.held_arm_pose(self.level_pose)[env_idx]
        airframe_goal = self.above_goal_tcp() + (state.position - self.tcp())
        depth = dict(zip(env_idx.tolist(), self.held_depth(env_idx).tolist()))
        for i in env_idx.tolist():
            arm_q = None if self.arm_pose is None else self.arm_pose[i]
            route = planner_for(self.env, i, depth[i], arm_q=arm_q).plan(state.position[i].cpu().numpy(), airframe_goal[i].cpu().numpy())
            self.planned[i] = route is not None
            self.route.set(i, route if route is not None else [airframe_goal[i].cpu().numpy()])

    def _kernel(self) -> Kernel:
        """The compiled `place_step` of this expert's law (fixed for its life: found once)."""
        if self._step_kernel is None:
            law = PlaceLaw(self.has_arm, self.pick is not None, float(self.max_yaw_rate), float(self.yaw_gain))
            self._step_kernel = shared_kernel(partial(_flat_place_step, law=law), "place_expert", law, _SOURCES,
                                              self.device)
        return self._step_kernel

    def step_inputs(self) -> list[torch.Tensor]:
        """This control step's tensors of `place_step` (the env's step context and signals, the expert's memory, the
        plan)."""
        ctx, info = self.env.current_step_context(), self.env.evaluate()
        arm = ()
        if self.has_arm:
            side = self.reaches_in(self.pick) if self.pick is not None else torch.zeros_like(self.levelling)
            arm = (self.arm_pose, self.level_pose, side, self.arm_params.lower, self.arm_params.upper)
        return [
            ctx.state.position, ctx.state.velocity, ctx.state.rotation, ctx.tcp, ctx.object_pose.p,
            info["set_down_steps"], ctx.is_supported,
            self.phase, self.timer, self.turned, self.stall_steps, self.stop_point, self.release_point, self.route.index,
            self.backed_off, self.levelling,
            self.evaluator.goal, self.heading, self.turn_at, self.route.points, self.route.length, *arm,
        ]

    def act(self) -> torch.Tensor:
        step = PlaceStep(*self._kernel()(*self.step_inputs()))
        self.phase, self.timer, self.turned, self.stall_steps = step.phase, step.timer, step.turned, step.stall_steps
        self.stop_point, self.release_point, self.route.index = step.stop_point, step.release_point, step.route_index
        self.backed_off, self.levelling, self.velocity_command = step.backed_off, step.levelling, step.velocity
        return step.action


class PlaceLaw(NamedTuple):
    """What fixes `place_step` besides its tensors (hashable: a compiled kernel's key)."""

    has_arm: bool
    after_pick: bool  # a chain's pick grasped the object (a side grasp backs off before it rises)
    max_yaw_rate: float
    yaw_gain: float


class PlaceStep(NamedTuple):
    """The expert's memory after one control step, and its action."""

    phase: torch.Tensor
    timer: torch.Tensor
    turned: torch.Tensor
    stall_steps: torch.Tensor
    stop_point: torch.Tensor
    release_point: torch.Tensor
    route_index: torch.Tensor
    backed_off: torch.Tensor
    levelling: torch.Tensor
    velocity: torch.Tensor  # the commanded velocity (m/s)
    action: torch.Tensor


def place_step(
    position, velocity, rotation, tcp, obj, set_down_steps, is_supported,
    phase, timer, turned, stall_steps, stop_point, release_point, route_index, backed_off, levelling,
    goal, heading, turn_at, route_points, route_length, *arm: torch.Tensor, law: PlaceLaw,
) -> PlaceStep:
    """One control step of the place expert as a pure function of tensors (`(N, ...)`; no branch on a tensor value):
    this step's airframe state, tool centre point, object position (its bottom centre), the task state's set-down
    time and support evidence, the expert's memory and the plan (goal, heading, the turn's point, the route). `arm`:
    the arm platform's carry and levelling poses, whether the chain's pick grasped from the side, the joint limits."""
    P = PlacePhase
    has_arm = law.has_arm
    yaw = torch.atan2(rotation[..., 1, 0], rotation[..., 0, 0])
    speed = torch.linalg.norm(velocity, dim=-1)
    hang = tcp - obj  # the object's bottom relative to the tool centre point
    above = goal + torch.tensor([0.0, 0.0, TRANSPORT_CLEARANCE_M], device=goal.device)
    xy_error = torch.linalg.norm((obj - goal)[:, :2], dim=-1)

    turned = turned | (wrap_angle(heading - yaw).abs() < TURN_TOLERANCE_RAD)
    turning = ~turned & (phase == P.TRANSPORT)
    phase, timer, _ = goto_phase(phase, timer, P.TRANSPORT, turned & (torch.linalg.norm(obj - above, dim=-1) < 0.04),
                                 P.ALIGN)
    phase, timer, _ = goto_phase(phase, timer, P.ALIGN, (xy_error < ALIGN_TOLERANCE_M) & (speed < SETTLED_MPS),
                                 P.DESCEND)
    # Release on what the task state shows (Place `progress` = the set-down time), never on a private timer: a
    # policy that sees the same inputs can learn when to open (docs/experiments.md, "What fails: the release").
    stalled = (phase == P.DESCEND) & ((obj[:, 2] - goal[:, 2]) < STALL_HEIGHT_M) & (speed < STOPPED_MPS)
    stall_steps = torch.where(stalled, stall_steps + 1, torch.zeros_like(stall_steps))
    phase, timer, _ = goto_phase(phase, timer, P.STOP, set_down_steps == 0, P.DESCEND)  # the support let go: press again
    phase, timer, stopped = goto_phase(phase, timer, P.DESCEND, set_down_steps >= SET_DOWN_STEPS, P.STOP)
    stop_point = torch.where(stopped[:, None], tcp, stop_point)
    phase, timer, opened = goto_phase(phase, timer, P.STOP,
                                      (speed < STOPPED_MPS) & (set_down_steps >= SET_DOWN_STEPS + STOPPED_STEPS), P.OPEN)
    phase, timer, stall_opened = goto_phase(phase, timer, P.DESCEND, stall_steps >= STALL_STEPS, P.OPEN)
    opened = opened | stall_opened
    release_point = torch.where(opened[:, None], tcp, release_point)
    phase, timer, _ = goto_phase(phase, timer, P.OPEN, timer >= OPEN_STEPS, P.RETREAT)
    risen = tcp[:, 2] >= release_point[:, 2] + RETREAT_HEIGHT_M - 0.02
    phase, timer, _ = goto_phase(phase, timer, P.RETREAT, risen, P.HOVER)
    timer = timer + 1

    target = above + hang
    waypoint, last, route_index = route_target(route_points, route_length, route_index, position)
    en_route = (phase == P.TRANSPORT) & ~last
    target = torch.where(en_route[:, None], waypoint + (tcp - position), target)
    target = torch.where(turning[:, None], turn_at + (tcp - position), target)  # the airframe holds
    contact = goal + hang - torch.tensor([0.0, 0.0, 0.01], device=goal.device)  # aim 1 cm into the surface
    target = torch.where((phase == P.DESCEND)[:, None], contact, target)
    on_surface = (phase == P.DESCEND) & ((obj[:, 2] - goal[:, 2]) < 0.004)
    press = tcp - torch.tensor([0.0, 0.0, 1.0], device=goal.device)  # far below: max_speed sets the push
    target = torch.where(on_surface[:, None], press, target)
    target = torch.where((phase == P.STOP)[:, None], tcp, target)  # zero velocity while the jaws still hold it
    # ... except on the arm: the support pushing up at the grasp point, 0.24 m ahead of the centre of mass, pitches
    # the airframe and it creeps backwards (14 cm over 8 s in a drawer, dragging the object off the goal), so it
    # holds the point where it stopped
    holding = (phase == P.STOP) & has_arm
    target = torch.where(holding[:, None], stop_point, target)
    # Open fingers clear a wide object by a few mm a side (a 102 mm can in the 110 mm jaws): from the release on,
    # hold the release point (a position hold that pulls a drift back) until the retreat lifts straight up.
    opening = release_point
    retreat = release_point + torch.tensor([0.0, 0.0, RETREAT_HEIGHT_M], device=goal.device)
    if law.after_pick and has_arm:
        # A side grasp (after a reach-in) has the palm a centimetre off the object's side: rising straight up dragged
        # it over the object, and the airframe's settling as the fingers let go pushed it into a can (collisions
        # after the release). The hand eases back while the fingers open and backs off along the forearm first.
        side = arm[2]
        forward = torch.stack([torch.cos(heading), torch.sin(heading), torch.zeros_like(heading)], -1)
        back_off = release_point - SIDE_BACK_OFF_M * forward
        backed_off = backed_off | ((phase >= P.RETREAT) & (torch.linalg.norm((tcp - back_off)[:, :2], dim=-1) < 0.02))
        backed = torch.where(backed_off[:, None], retreat - SIDE_BACK_OFF_M * forward, back_off)
        retreat = torch.where(side[:, None], backed, retreat)
        opening = torch.where(side[:, None], release_point - SIDE_EASE_BACK_M * forward, opening)
    target = torch.where((phase == P.OPEN)[:, None], opening, target)
    target = torch.where((phase == P.RETREAT)[:, None] | (phase == P.HOVER)[:, None], retreat, target)
    near = (obj[:, 2] - goal[:, 2]) < TOUCH_ZONE_M
    max_speed = torch.full_like(speed, TRANSPORT_SPEED_MPS)
    max_speed = torch.where(phase == P.ALIGN, torch.full_like(max_speed, 0.15), max_speed)
    max_speed = torch.where(phase == P.DESCEND, torch.where(near, TOUCH_SPEED_MPS, DESCEND_SPEED_MPS), max_speed)
    max_speed = torch.where(on_surface, torch.full_like(max_speed, PRESS_SPEED_MPS), max_speed)
    max_speed = torch.where(phase == P.STOP, torch.zeros_like(max_speed), max_speed)
    max_speed = torch.where(holding, torch.full_like(max_speed, HOLD_SPEED_MPS), max_speed)
    max_speed = torch.where(phase == P.OPEN, torch.full_like(max_speed, HOLD_SPEED_MPS), max_speed)
    max_speed = torch.where(phase == P.RETREAT, torch.full_like(max_speed, RETREAT_SPEED_MPS), max_speed)
    max_speed = torch.where(phase == P.HOVER, torch.full_like(max_speed, 0.1), max_speed)
    released = (phase == P.OPEN) | (phase == P.RETREAT) | (phase == P.HOVER)
    gripper = torch.where(released, torch.ones_like(speed), torch.full_like(speed, -1.0))
    # Pressing on the surface sinks straight down, which holds no horizontal position: on the arm the support's push
    # at the grasp point pitches the airframe and it crept back 1.5 cm/s, dragging a master chef can 10 cm across a
    # drawer's floor off its goal (too fast for the stall release); there the press holds the goal's xy.
    hold_xy = (POSITION_GAIN * (contact - tcp)[:, :2]).clamp(-HOLD_SPEED_MPS, HOLD_SPEED_MPS)
    press_velocity = torch.cat([hold_xy, torch.full_like(hold_xy[:, :1], -PRESS_SPEED_MPS)], -1)
    arm_action = None
    if has_arm:  # level once the support carries part of the object (a drooped can touches with its rim) ...
        arm_pose, level_pose, _, lower, upper = arm
        drooped = (arm_pose != level_pose).any(-1)
        levelling = levelling | (drooped & (phase == P.DESCEND) & is_supported)
        arm_target = torch.where((levelling | on_surface | (phase >= P.STOP))[:, None], level_pose, arm_pose)
        arm_action = normalized_arm_action(arm_target, lower, upper)
    # ... and sink as on the surface meanwhile: the forearm levels only as fast as the drone lowers the grasp point
    pressing = (on_surface | (levelling & (phase == P.DESCEND))) & has_arm
    velocity_cmd = tracking_velocity(tcp, target, max_speed, POSITION_GAIN, (pressing, press_velocity))
    yaw_rate = yaw_rate_towards(yaw, heading, law.max_yaw_rate, law.yaw_gain)
    action = expert_action(velocity_cmd, yaw_rate, gripper, arm_action)
    return PlaceStep(phase, timer, turned, stall_steps, stop_point, release_point, route_index, backed_off, levelling,
                     velocity_cmd, action)


def _flat_place_step(*tensors: torch.Tensor, law: PlaceLaw) -> tuple[torch.Tensor, ...]:
    return tuple(place_step(*tensors, law=law))


_HERE = Path(__file__).resolve().parent
_ENVS = _HERE.parent / "envs"
# every module `place_step` reads code or constants from: a change to any of them is a new compiled package
_SOURCES = [_HERE / "place.py", _HERE / "base.py", _HERE / "motion.py", _HERE / "route.py", _ENVS / "observations.py",
            _ENVS / "platforms.py", _ENVS / "control" / "arm.py"]


__all__ = ["PlaceExpert", "PlacePhase", "wrap_angle"]
