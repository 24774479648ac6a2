"""Open / Close expert (arm platform): approach the handle, pinch, drive the door or drawer, release, retract.

The arm reaches forward; the wrist is rolled so the fingers close across the handle (horizontally on the fridge's
vertical bar, vertically on the drawer's horizontal handle). While pinched the controller is in contact mode (limp
shoulder), and the expert pulls or pushes the handle along the door's current outward normal, which follows the
hinge arc for the fridge and is fixed for the drawer; the heading follows the door (a grasped door sets it).
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
import torch

from ..envs.control.arm import arm_point_positions_body
from ..envs.scenes import articulated
from .base import SkillExpert
from .motion import TURN_TOLERANCE_RAD, wrap_angle
from .planner import can_turn_in_place, planner_for, route_at_some_heading
from .route import RouteFollower

STANDOFF_M = 0.14  # pre-insert: the tool centre point this far out along the handle's normal
APPROACH_SPEED_MPS = 0.45
INSERT_SPEED_MPS = 0.05
AT_HANDLE_M = 0.008
# The insertion corridor: the tool centre point between the standoff point and the handle, this close to the handle's
# normal, facing the handle, slow. The expert's own flight stops at the standoff point and inserts from there; a
# policy it labels (DAgger) may fly on into the corridor, and is told to insert from where it is, not to back out.
CORRIDOR_M = 0.025
CORRIDOR_SPEED_MPS = 0.15
ROUTE_END_M = 0.05  # an approach flown at another heading turns to face the handle this close to its route's end
PINCH_CONFIRM_STEPS = 3
# The door and drawer resist with Coulomb friction (7 N / 2.5 N at the handle): the velocity loop must wind its
# integrator up to the tilt that pulls that hard, so a brisk commanded speed gets them moving within seconds.
DRIVE_SPEED_MPS = {"fridge": 0.25, "drawer": 0.3}
OPEN_MARGIN = 0.06  # drive a little past the spec's threshold, so the goal holds after release
# Before a pick from inside the fridge the door goes further than the threshold: at 0.95 (1.8 rad, 103 deg) its free
# end stands 0.16 m beyond the carcass's side, which leaves the pick's route from the handle round the door to the
# fridge's front the room the rotor disks need (at the threshold's 0.81 the door stands square across that way).
OPEN_FOR_REACH_IN = 0.95
EASE_ZONE = 0.15  # progress over which the drive slows down before the goal
MIN_EASE = 0.3
HINGE_PULL_ACCEL = 2.7  # m/s^2: 7 N of door friction on the 2.58 kg arm platform
DRAWER_PULL_ACCEL = 1.0  # m/s^2: 2.5 N of drawer friction
HEIGHT_GAIN = 1.5  # 1/s
SPEED_GAIN = 4.0  # 1/s: extra acceleration per m/s below the drive speed
MAX_PULL_ACCEL = 4.0
LATERAL_GAIN = 2.0  # 1/s: sideways velocity tracking while driving
# Pushing a door shut through a pinched handle is pushing a stick: the door's 7 N reaction at the tool centre point,
# 0.45 m ahead, turns the drone away from the normal faster than its rotor-drag yaw torque can turn it back. With the
# tool centre point held by the handle, the airframe's sideways position *is* its heading about the handle, so the
# drive steers the airframe onto the line through the handle along the normal (and sweeps it round with the door).
CENTRE_GAIN = 3.0  # 1/s: sideways velocity per metre off that line
UNWOUND_TILT_RAD = math.radians(4.0)
UNWIND_MAX_STEPS = 40
DRIVE_YAW_GAIN = 1.5  # 1/s: pinched, the door damps the heading, so it can follow the door's turn closely
CLOSED_TARGET = 0.004
RELEASE_STEPS = 8
RETRACT_M = 0.20
SETTLE_SPEED_MPS = 0.1
# The drawer handle (0.75 m) sits 0.15 m under the counter top: with the forearm level at the working pose the rotor
# disks would be under the counter's edge, so the shoulder pitches down 0.55 rad (elbow -0.55, forearm level) and
# the drone hovers with its disks ~7 cm above the counter.
REACH_POSE = {"fridge": (-0.12, 0.12, 0.0), "drawer": (0.55, -0.55, math.pi / 2)}


class ArticulationPhase(IntEnum):
    APPROACH = 0
    INSERT = 1
    PINCH = 2
    DRIVE = 3
    UNWIND = 4
    RELEASE = 5
    RETRACT = 6
    SETTLE = 7


class ArticulationExpert(SkillExpert):
    def __init__(self, env, evaluator, reach_in_next: bool = False):
        super().__init__(env, evaluator)
        self.reach_in_next = reach_in_next
        self.route = RouteFollower(self.n, self.device)
        self.planned = torch.ones(self.n, dtype=torch.bool, device=self.device)
        # the approach is flown at `heading` and turns in place to face the handle where the route ends (the route
        # at the handle's heading is tried first; with the arm reaching out a start may only have one at another)
        self.heading = torch.zeros(self.n, device=self.device)
        self.turned = torch.ones(self.n, dtype=torch.bool, device=self.device)
        self.arrived = torch.zeros(self.n, dtype=torch.bool, device=self.device)  # at the route's end (latched)
        self.release_point = torch.zeros(self.n, 3, device=self.device)
        self.release_normal = torch.zeros(self.n, 3, device=self.device)
        self.is_drawer = torch.zeros(self.n, dtype=torch.bool, device=self.device)
        self.reach_pose = torch.zeros(self.n, 3, device=self.device)
        self.unfolded = torch.zeros(self.n, dtype=torch.bool, device=self.device)  # the retract has unfolded the arm
        self.hold_point = torch.zeros(self.n, 3, device=self.device)  # airframe target once unfolded
        self.hinge_sign = torch.ones(self.n, device=self.device)  # world yaw change per unit of door angle
        self.pinch_height = torch.zeros(self.n, device=self.device)

    def handle(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Grasp point and outward normal `(N, 3)` of each env's handle, in the fixture's current state."""
        ev = self.evaluator
        frames = [articulated.handle_frame(name, f.root_pose.p, f.root_pose.q, f.get_qpos()[:, 0]) for name, f in zip(ev.names, ev.fixtures)]
        point = ev._per_env([fr[0] for fr in frames])
        normal = ev._per_env([fr[1] for fr in frames])
        return point, normal

    def reset(self, env_idx):
        super().reset(env_idx)
        ev = self.evaluator
        names = [ev.names[int(k)] for k in ev.fixture_id[env_idx]]
        self.is_drawer[env_idx] = torch.tensor([n == "drawer" for n in names], device=self.device)
        self.reach_pose[env_idx] = torch.tensor([REACH_POSE[n] for n in names], device=self.device)
        self.unfolded[env_idx] = False
        point, normal = self.handle()
        state = self.state()
        yaw = torch.atan2(-normal[:, 1], -normal[:, 0])
        self.hinge_sign[env_idx] = self._hinge_sign()[env_idx]
        pre_tcp = point + STANDOFF_M * normal
        airframe_goal = pre_tcp - self._tcp_offset_world(yaw, self.reach_pose)
        for i in env_idx.tolist():
            start, goal, facing = state.position[i].cpu().numpy(), airframe_goal[i].cpu().numpy(), float(yaw[i])
            heading, route = self._plan(i, start, goal, facing, float(state.yaw[i]))
            self.planned[i] = route is not None
            self.heading[i], self.turned[i], self.arrived[i] = heading, heading == facing, False
            self.route.set(i, route if route is not None else [goal])

    def _plan(self, i: int, start: np.ndarray, goal: np.ndarray, facing: float, yaw: float) -> tuple[float, list | None]:
        """The route facing the handle, or else the first candidate heading with a route after which the drone can
        turn in place at the route's end to face the handle."""
        toward = math.atan2(goal[1] - start[1], goal[0] - start[0])
        candidates = [facing, yaw, toward] + [facing + k * math.pi / 2 for k in (1, -1, 2)]
        planner_at = lambda h: planner_for(self.env, i, heading=h, arm_q=self.reach_pose[i])  # noqa: E731
        return route_at_some_heading(
            planner_at, start, [goal], candidates, lambda h: h == facing or can_turn_in_place(planner_at, goal, h, facing)
        )

    def _hinge_sign(self) -> torch.Tensor:
        """+1 where opening the door turns its normal counter-clockwise (seen from above), -1 otherwise."""
        ev = self.evaluator
        signs = []
        for name, f in zip(ev.names, ev.fixtures):
            q = f.get_qpos()[:, 0]
            n0 = articulated.handle_frame(name, f.root_pose.p, f.root_pose.q, q)[1]
            n1 = articulated.handle_frame(name, f.root_pose.p, f.root_pose.q, q + 0.01)[1]
            signs.append(torch.sign(n0[:, 0] * n1[:, 1] - n0[:, 1] * n1[:, 0]) + (n0[:, 0] * n1[:, 1] == n0[:, 1] * n1[:, 0]).float())
        return ev._per_env(signs)

    def _tcp_offset_world(self, yaw: torch.Tensor, arm_q: torch.Tensor) -> torch.Tensor:
        """Tool centre point relative to the airframe centre for a level drone at `yaw` with the arm at `arm_q`."""
        g = arm_point_positions_body(arm_q, self.platform.arm)["grasp"]
        c, s = torch.cos(yaw), torch.sin(yaw)
        return torch.stack([c * g[:, 0] - s * g[:, 1], s * g[:, 0] + c * g[:, 1], g[:, 2]], -1)

    def act(self):
        P = ArticulationPhase
        ev, info = self.evaluator, self.env.evaluate()
        state, tcp = self.state(), self.tcp()
        point, normal = self.handle()
        yaw_target = torch.atan2(-normal[:, 1], -normal[:, 0])
        progress = info["articulation_progress"]
        pinched = info["is_handle_pinched"]
        opening = ev.skill == "open"
        open_goal = (ev.open_threshold[ev.fixture_id] + OPEN_MARGIN).clamp(max=0.99)
        open_goal = open_goal.clamp(min=OPEN_FOR_REACH_IN) if self.reach_in_next else open_goal
        goal_reached = (progress >= open_goal) if opening else (progress <= CLOSED_TARGET)

        waypoint, last = self.route.target(state.position)
        pre_tcp = point + STANDOFF_M * normal
        self.arrived |= last & (torch.linalg.norm(waypoint - state.position, dim=-1) < ROUTE_END_M)
        self.turned |= self.arrived & (wrap_angle(yaw_target - state.yaw).abs() < TURN_TOLERANCE_RAD)
        at_standoff = last & self.turned & (torch.linalg.norm(tcp - pre_tcp, dim=-1) < 0.02) & (state.velocity.norm(dim=-1) < 0.05)
        self.goto(P.APPROACH, at_standoff | self._in_corridor(tcp, point, normal, yaw_target, state), P.INSERT)
        self.goto(P.INSERT, torch.linalg.norm(tcp - point, dim=-1) < AT_HANDLE_M, P.PINCH)
        started_drive = self.goto(P.PINCH, pinched & (self.timer >= PINCH_CONFIRM_STEPS), P.DRIVE)
        self.goto(P.DRIVE, goal_reached, P.UNWIND)
        tilt = info["tilt"]
        released = self.goto(P.UNWIND, (tilt < UNWOUND_TILT_RAD) | (self.timer >= UNWIND_MAX_STEPS), P.RELEASE)
        self.release_point = torch.where(released[:, None], tcp, self.release_point)
        self.release_normal = torch.where(released[:, None], normal, self.release_normal)
        self.goto(P.RELEASE, ~pinched & (self.timer >= RELEASE_STEPS), P.RETRACT)
        clear = torch.linalg.norm(tcp - self.release_point, dim=-1) > RETRACT_M - 0.03
        self.goto(P.RETRACT, clear & info["is_arm_retracted"], P.SETTLE)
        self.advance_timer()

        phase = self.phase
        working = self.arm_rest.expand(self.n, 3)
        # the arm keeps its reach pose until half the retract is flown: unfolding at the handle raised the wrist to
        # within 3 cm of the counter's edge above the drawer (the clearance check's limit)
        backed = torch.linalg.norm(tcp - self.release_point, dim=-1) > RETRACT_M / 2
        unfolding = (((phase == P.RETRACT) & backed) | (phase == P.SETTLE)) & ~self.unfolded
        self.unfolded |= unfolding  # latched: unfolding moves the TCP
        # ... and from then on the airframe, not the tool centre point, is held where the retract ends: the unfolded
        # TCP stands 0.2 m higher and 0.47 m ahead, so a TCP target sank the drone towards the counter and its heading's
        # slow swing (the arm's 0.12 N m yaw) walked it round in circles (close clearance failures, docs/expert.md)
        back = self.release_point + RETRACT_M * self.release_normal
        self.hold_point = torch.where(unfolding[:, None], state.position + (back - tcp), self.hold_point)
        arm = torch.where(self.unfolded[:, None], working, self.reach_pose)
        drive_speed = torch.where(self.is_drawer, DRIVE_SPEED_MPS["drawer"], DRIVE_SPEED_MPS["fridge"])
        direction = normal if opening else -normal
        target = pre_tcp
        routing = (phase == P.APPROACH) & ~(last & self.turned)  # the route, then the turn in place at its end
        target = torch.where(routing[:, None], waypoint + (tcp - state.position), target)
        target = torch.where((phase == P.INSERT)[:, None] | (phase == P.PINCH)[:, None], point, target)
        target = torch.where((phase == P.DRIVE)[:, None], tcp + direction, target)  # far along: speed sets the pace
        target = torch.where((phase == P.RELEASE)[:, None], tcp, target)
        leaving = (phase == P.RETRACT) | (phase == P.SETTLE)
        target = torch.where(leaving[:, None], back, target)
        target = torch.where((leaving & self.unfolded)[:, None], self.hold_point + (tcp - state.position), target)
        max_speed = torch.full((self.n,), APPROACH_SPEED_MPS, device=self.device)
        max_speed = torch.where((phase == P.APPROACH) & last, torch.full_like(max_speed, 0.15), max_speed)
        max_speed = torch.where((phase == P.INSERT) | (phase == P.PINCH), torch.full_like(max_speed, INSERT_SPEED_MPS), max_speed)
        # ease off over the last 15% so the pull (and the tilt it needs) is small when the handle is let go
        remaining = ((open_goal - progress) if opening else (progress - CLOSED_TARGET)) / EASE_ZONE
        drive_speed = drive_speed * remaining.clamp(MIN_EASE, 1.0)
        max_speed = torch.where(phase == P.DRIVE, drive_speed, max_speed)
        max_speed = torch.where(phase == P.RELEASE, torch.zeros_like(max_speed), max_speed)
        max_speed = torch.where((phase == P.RETRACT) | (phase == P.SETTLE), torch.full_like(max_speed, SETTLE_SPEED_MPS), max_speed)
        closed = (phase == P.PINCH) | (phase == P.DRIVE) | (phase == P.UNWIND)
        gripper = torch.where(closed, torch.full((self.n,), -1.0, device=self.device), torch.ones(self.n, device=self.device))
        # While the door turns, the heading turns with it: its joint rate is the feedforward (the drawer slides: 0).
        door_rate = ev._per_env([f.get_qvel()[:, 0] for f in ev.fixtures])
        feedforward = torch.where((phase == P.DRIVE) & ~self.is_drawer, door_rate * self.hinge_sign, torch.zeros_like(door_rate))
        yaw_gain = torch.where((phase == P.DRIVE) | (phase == P.UNWIND), DRIVE_YAW_GAIN, self.yaw_gain)
        xi = self.env.agent.body_controller.memory.xi
        # The door's pull direction turns as it swings, faster than the velocity loop's world-frame integrator can
        # follow; so for the hinge the expert commands the horizontal *acceleration* it wants along the current normal
        # (a friction feedforward plus speed tracking), converted through the loop's law with the privileged xi.
        speed_along = (state.velocity[:, :2] * direction[:, :2]).sum(-1)
        lateral = state.velocity[:, :2] - speed_along[:, None] * direction[:, :2]
        sideways = self._centring_velocity(point, yaw_target, feedforward, state.position)
        sideways = sideways - (sideways * direction[:, :2]).sum(-1, keepdim=True) * direction[:, :2]
        friction = torch.where(self.is_drawer, DRAWER_PULL_ACCEL, HINGE_PULL_ACCEL)
        accel = (friction + SPEED_GAIN * (drive_speed - speed_along)).clamp(0.0, MAX_PULL_ACCEL)
        wanted = accel[:, None] * direction[:, :2] + LATERAL_GAIN * (sideways - lateral)
        pull = self._horizontal_velocity_for(wanted, state.velocity, xi)
        # Unwind: the door's friction still holds the handle; command no acceleration along the normal (3 e_v + xi = 0
        # there, privileged xi), so the pull fades before the fingers open, and keep centring sideways: the sweep's
        # 0.2 m/s round the handle would otherwise carry the drone on towards whatever stands beside the door.
        unwind = self._horizontal_velocity_for(LATERAL_GAIN * (sideways - lateral), state.velocity, xi)
        # With the shoulder limp (contact mode) the arm is a free strut: the airframe, not the tool centre point,
        # must hold its height, or pushing folds the arm and the drone climbs into the fixture.
        self.pinch_height = torch.where(started_drive, state.position[:, 2], self.pinch_height)
        pull[:, 2] = (HEIGHT_GAIN * (self.pinch_height - state.position[:, 2])).clamp(-0.3, 0.3)
        unwind[:, 2] = pull[:, 2]
        drive = phase == P.DRIVE
        override = torch.where(drive[:, None], pull, unwind)
        yaw_target = torch.where((phase == P.APPROACH) & ~self.arrived & ~self.turned, self.heading, yaw_target)
        return self.action(
            target, max_speed, yaw_target, gripper, arm_target=arm, yaw_rate_feedforward=feedforward, yaw_gain=yaw_gain,
            velocity_override=(drive | (phase == P.UNWIND), override),
        )

    @staticmethod
    def _in_corridor(tcp: torch.Tensor, point: torch.Tensor, normal: torch.Tensor, facing: torch.Tensor,
                     state) -> torch.Tensor:
        """`(N,)` whether the tool centre point stands in the insertion corridor (CORRIDOR_M), facing the handle."""
        offset = tcp - point
        along = (offset * normal).sum(-1)
        lateral = torch.linalg.norm(offset - along[:, None] * normal, dim=-1)
        aligned = wrap_angle(facing - state.yaw).abs() < TURN_TOLERANCE_RAD
        slow = state.velocity.norm(dim=-1) < CORRIDOR_SPEED_MPS
        return (along > -AT_HANDLE_M) & (along < STANDOFF_M + CORRIDOR_M) & (lateral < CORRIDOR_M) & aligned & slow

    def _centring_velocity(self, point: torch.Tensor, facing: torch.Tensor, door_yaw_rate: torch.Tensor, position: torch.Tensor) -> torch.Tensor:
        """Horizontal airframe velocity `(N, 2)` that keeps it where a drone facing the door with its tool centre
        point at the handle would be: that point's sweep with the door plus a pull back onto it."""
        offset = -self._tcp_offset_world(facing, self.env.agent.arm_qpos())[:, :2]  # handle -> airframe
        sweep = door_yaw_rate[:, None] * torch.stack([-offset[:, 1], offset[:, 0]], -1)
        return sweep + CENTRE_GAIN * (point[:, :2] + offset - position[:, :2])

    @staticmethod
    def _horizontal_velocity_for(accel_xy: torch.Tensor, velocity: torch.Tensor, xi: torch.Tensor) -> torch.Tensor:
        """Velocity command whose horizontal acceleration command (3 e_v + xi, Eq. force) equals `accel_xy`;
        vertical: hold (zero velocity)."""
        v_xy = velocity[:, :2] + (accel_xy - xi[:, :2]) / 3.0
        return torch.cat([v_xy.clamp(-0.6, 0.6), torch.zeros_like(xi[:, 2:])], -1)
