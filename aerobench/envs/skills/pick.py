"""Pick: grasp the object and hold it above its lift threshold (spec appendix, Pick completion check)."""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path
from typing import NamedTuple

import torch
from mani_skill.utils.registration import register_env
from mani_skill.utils.structs.pose import Pose

from ...accel import Kernel, shared_kernel
from ..checks import FailureCause, SafetyLimits, consecutive
from ..control.arm import arm_point_positions_body
from ..control.so3 import quat_wxyz_to_matrix
from ..geometry import level_airframe_room
from ..observations import wrap_to_period
from ..scenes import articulated
from ..tasks import instruction
from .base import AeroSkillEnv
from .evaluator import GoalFeatures, SkillEvaluator
from .starts import SUPPORT_KINDS

PICK_LIFT_M = 0.10  # lift threshold above the instance's own resting height (so it differs per instance)
PICK_HOLD_STEPS = 10  # consecutive control steps grasped and lifted (0.5 s)
START_ABOVE_OBJECT_M = 0.15  # the tool centre point starts at least this far above the object's top
ROUND_SHAPES = ("cylinder", "bowl")  # round about z: any heading on the room axes grasps them
# Supports inside a fixture, open only on its front (the support's +x): the grasp heading points in through the front,
# and a box stands with a grasp axis along it (the fridge's side walls leave no other way in). The airframe stays
# outside, its rotor disks clear of the carcass's front and of the open door's plane, and the arm reaches in: the X500's
# disks reach 0.32 m ahead of the airframe centre and the arm's tool centre point 0.47 m, so the arm gets about 11 cm
# past the fridge's front. Objects on a fridge shelf stand square to the front, within that reach, on the shelf's
# latch half (a tool centre point on the hinge half puts a rotor disk through the open door).
ENCLOSED_KINDS = ("fridge_shelf",)
ENCLOSED_YAW_NOISE_RAD = 0.03
ENCLOSED_ROTOR_CLEARANCE_M = 0.035  # rotor disks to the fridge's front and to the open door's plane, at the grasp
ENCLOSED_EDGE_MARGIN_M = 0.005  # the object's front face this far behind the shelf board's front edge
# The arm's palm stands 6 cm back from its grasp point (the gripper's 10 cm): grasped top down at half height, an object
# taller than 12 cm (the master chef can, the cracker and sugar boxes) meets the palm, so the arm grasps those higher,
# its palm this far above the object's top.
TOP_DOWN_PALM_MARGIN_M = 0.015
# The arm's top-down grasp point is 0.24 m ahead of the airframe, so of a box's two grasp headings the one nearer the
# drone's yaw can stand the airframe in a wall behind the object (an object on a counter against a wall: rotors 5 cm
# into it, and the pick flew into the wall). That heading is kept unless its rotor disks would come closer than this
# to the scene; then the grasp heading with the most room is planned.
TOP_DOWN_ROOM_M = 0.08


def enclosed_reach_m(platform, yaw_noise: float = ENCLOSED_YAW_NOISE_RAD) -> tuple[float, float, float]:
    """For a grasp up to `yaw_noise` off straight in through a fixture's front: how far past the front the tool
    centre point reaches with the rotor disks `ENCLOSED_ROTOR_CLEARANCE_M` before it, how far the disks reach
    sideways of the airframe centre, and how far the airframe centre sits sideways of the tool centre point."""
    rotors, tcp_ahead = platform.rotors, platform.grasp_point_m[0]
    c, s = math.cos(yaw_noise), math.sin(yaw_noise)
    disks = rotors.arm_m * (c + s) + rotors.disk_radius_m
    return tcp_ahead * c - disks - ENCLOSED_ROTOR_CLEARANCE_M, disks, tcp_ahead * s


def grasp_heading(object_yaw: torch.Tensor, current_yaw: torch.Tensor, is_round: torch.Tensor) -> torch.Tensor:
    """The heading that puts the closing axis (body y) along the object's x axis, the nearer of the two; objects that
    are round about z keep the current heading rounded to the room axes (supports are fitted for it)."""
    across = current_yaw + wrap_to_period(object_yaw + math.pi / 2 - current_yaw, math.pi)
    axis_aligned = current_yaw + wrap_to_period(-current_yaw, math.pi / 2)
    return torch.where(is_round, axis_aligned, across)


def pick_grasp_target(
    tcp: torch.Tensor, position: torch.Tensor, R: torch.Tensor, heading: torch.Tensor, enclosed: torch.Tensor,
    grasp_point: torch.Tensor, height: torch.Tensor, half_extent: torch.Tensor, grasps_rim: torch.Tensor, arm=None,
) -> torch.Tensor:
    """Where the tool centre point grasps `(N, 3)`: the object's planned grasp point (`grasp_point` in its frame, the
    object at `position` with rotation `R`); for the bowl (`grasps_rim`), the rim point whose radial direction is the
    closing axis (body y) of the planned `heading`, on the side nearer `tcp`. `arm`: the platform's `ArmSpec` (None
    for the gripper). A pure function of tensors (the pick expert's compiled step computes it too)."""
    planned = position + (R @ grasp_point[..., None])[..., 0]
    if arm is not None:  # top down (everywhere but an enclosure), the arm's palm clear of the object's top
        above_palm = height - grasp_point[:, 2] - (arm.palm_to_grasp_m - TOP_DOWN_PALM_MARGIN_M)
        planned = planned + torch.stack([torch.zeros_like(above_palm), torch.zeros_like(above_palm),
                                         above_palm.clamp_min(0.0) * ~enclosed], -1)
    zero = torch.zeros_like(heading)
    if arm is not None:
        # Reaching in, the palm meets the object's near face the same way: a box deeper along the approach than
        # twice the palm's 6 cm (the cracker box, 15.8 cm) stopped it 2 cm short of the centre (a collision at every
        # insertion), so the grasp point is drawn back until the palm keeps the same margin off the face. This
        # moves arm-platform grasps from a fridge shelf only (no learned policy is trained on them).
        behind = (half_extent[:, 1] - (arm.palm_to_grasp_m - TOP_DOWN_PALM_MARGIN_M)).clamp_min(0.0)
        forward = torch.stack([torch.cos(heading), torch.sin(heading), zero], -1)
        planned = planned - (behind * enclosed)[:, None] * forward
    radial = torch.stack([-torch.sin(heading), torch.cos(heading), zero], -1)
    side = torch.sign((radial * (tcp - position)).sum(-1, keepdim=True) + 1e-9)
    g = grasp_point  # a rim grasp's pinch point: rim radius (x) and height above the bottom (z)
    rim = position + g[:, :1] * side * radial + torch.stack([zero, zero, g[:, 2]], -1)
    return torch.where(grasps_rim[:, None], rim, planned)


class PickEvaluator(SkillEvaluator):
    skill = "pick"

    def __init__(self, env, where=()):
        super().__init__(env, where)
        self.kinds = self.where or env.setting.pick_supports
        self.rest_z = self.zeros()
        self.support_index = self.zeros(torch.long)
        self.support_row = torch.zeros(self.n, 9, device=self.device)  # its row of `env.supports`, kept at sampling
        self.free_height = self.zeros()  # ... and that row's free height above (read at every expert step)
        self.hold_streak = self.zeros(torch.long)
        specs = env.target_specs
        self.is_round = torch.tensor([s.shape in ROUND_SHAPES for s in specs], dtype=torch.bool, device=self.device)
        self.heading_period = torch.where(self.is_round, math.pi / 2, math.pi)
        self.heading = self.zeros()  # the grasp heading planned when the skill starts
        self.inward = self.zeros()  # enclosed supports: the heading through the fixture's front
        self.enclosed = self.zeros(torch.bool)
        self._update: Kernel | None = None  # the compiled `pick_update`, made at the first update
        self._every = torch.ones(self.n, dtype=torch.bool, device=self.device)  # `mine` in a single-skill env

    def sample(self, env_idx: torch.Tensor) -> torch.Tensor:
        """Put the target upright at a random spot of a random source support; `(M,)` whether one existed."""
        env = self.env
        index, ok = env.sample_supports(env_idx, self.kinds)
        bottom = env.sample_on_support(env_idx, index, env.target_radius[env_idx] + 0.04)
        row = env.supports[env_idx, index]
        enclosed_ids = torch.tensor([SUPPORT_KINDS.index(k) for k in ENCLOSED_KINDS], device=self.device)
        enclosed = (row[:, 6][:, None] == enclosed_ids).any(-1)
        inward = row[:, 5] + math.pi
        yaw = (env.episode_rng.rand(env_idx) * 2 - 1) * math.pi
        # the closing axis (body y) lies along the object's x: x across the way in
        noise = (env.episode_rng.rand(env_idx) * 2 - 1) * ENCLOSED_YAW_NOISE_RAD
        yaw = torch.where(enclosed, inward - math.pi / 2 + noise, yaw)
        if enclosed.any():
            # only the enclosed envs draw their spot inside: whether an env draws never depends on another env
            u = torch.zeros(len(env_idx), 2, device=self.device)
            u[enclosed] = env.episode_rng.rand(env_idx[enclosed], 2)
            reachable, fits = self._within_reach_inside(env_idx, row, u)
            bottom = torch.where(enclosed[:, None], reachable, bottom)
            ok = ok & (fits | ~enclosed)
        self.enclosed[env_idx], self.inward[env_idx] = enclosed, inward
        env.place_object(env.target, env_idx, bottom, yaw)
        self.support_index[env_idx] = index
        self.support_row[env_idx] = row
        self.free_height[env_idx] = row[:, 8]
        self.rest_z[env_idx] = bottom[:, 2]
        return ok

    def _within_reach_inside(self, env_idx: torch.Tensor, row: torch.Tensor,
                             u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """A point `(M, 3)` on each (fridge-shelf) support row where the arm reaches the object from in front of the
        fridge (`ENCLOSED_KINDS`), at uniform draws `u` `(M, 2)` (depth, side), and `(M,)` whether the object fits
        there at all."""
        env = self.env
        reach, disks, sideways = enclosed_reach_m(env.platform)
        fridge = articulated.get_fixture_spec("fridge")
        outer = articulated.FRIDGE_WIDTH_M / 2  # the open door's inner face stands on this plane (or beyond it)
        inner = outer - articulated.FRIDGE_WALL_M
        hinge = math.copysign(1.0, fridge.hinge_point[1])  # the door's hinge side, along the support's y
        setback = articulated.FRIDGE_SHELF_SETBACK_M
        front = row[:, 2] + articulated.SUPPORT_EDGE_MARGIN_M + setback  # the fridge's front, support frame
        across, along = env.target_half_extent[env_idx, 0], env.target_half_extent[env_idx, 1]  # x stands across
        rim = torch.where(env.target_grasps_rim[env_idx], env.target_grasp_point[env_idx, 0], 0.0)
        depth_lo = setback + along + ENCLOSED_EDGE_MARGIN_M
        depth_hi = torch.full_like(depth_lo, reach)
        # away from the hinge: the object on the board, and the open fingers' outer faces (either side of the grasp
        # point, which a rim grasp has off the object's centre) clear of the side wall (a box 5 mm off the wall left
        # the far finger in it and the grasp never closed)
        open_half = env.platform.gripper.max_opening_m / 2 + env.platform.gripper.finger_thickness_m
        side_lo = -inner + torch.maximum(across, open_half - rim) + ENCLOSED_EDGE_MARGIN_M
        side_hi = outer - ENCLOSED_ROTOR_CLEARANCE_M - disks - sideways - rim  # the disks clear of the door's plane
        depth = depth_lo + u[:, 0] * (depth_hi - depth_lo).clamp_min(0.0)
        side = side_lo + u[:, 1] * (side_hi - side_lo).clamp_min(0.0)
        local = torch.stack([front - depth, hinge * side], -1)
        c, s = torch.cos(row[:, 5]), torch.sin(row[:, 5])
        xy = row[:, 0:2] + torch.stack([c * local[:, 0] - s * local[:, 1], s * local[:, 0] + c * local[:, 1]], -1)
        return torch.cat([xy, row[:, 4:5]], -1), (depth_hi >= depth_lo) & (side_hi >= side_lo)

    def clear_height(self) -> torch.Tensor:
        """`(N,)` the free height above each env's source support (large where nothing is above)."""
        return self.free_height

    def begin(self, env_idx):
        self.rest_z[env_idx] = self.env.target.pose.p[env_idx, 2]
        self.hold_streak[env_idx] = 0
        self.plan_heading(env_idx)

    def plan_heading(self, env_idx):
        """Plan the grasp heading from the drone's heading now: at the skill's start, and again by a demonstrator
        that first turned on the spot to face the object."""
        pose = self.env.target.pose
        object_yaw = 2 * torch.atan2(pose.q[:, 3], pose.q[:, 0])
        reference = torch.where(self.enclosed, self.inward, self.env.agent.airframe_state().yaw)
        planned = grasp_heading(object_yaw, reference, self.is_round)
        planned = torch.where(self.enclosed & self.is_round, self.inward, planned)  # straight in through the front
        if self.env.platform.arm is not None:
            planned = torch.where(self.enclosed, planned, self._roomiest_top_down_heading(planned))
        self.heading[env_idx] = planned[env_idx]

    def _roomiest_top_down_heading(self, planned: torch.Tensor) -> torch.Tensor:
        """`(N,)` the planned grasp heading, or where the arm platform's airframe would stand within TOP_DOWN_ROOM_M of
        the scene above the object at it, the equivalent grasp heading (by the object's symmetry) with the most room."""
        env, arm = self.env, self.env.platform.arm
        grasp = arm_point_positions_body(torch.tensor([arm.top_down_pose_rad], device=self.device), arm)["grasp"]
        turns = torch.arange(4, device=self.device)
        headings = planned[:, None] + turns[None] * self.heading_period[:, None]  # (N, 4); repeats for boxes
        n = len(headings)
        boxes = env.obstacle_boxes(torch.arange(n, device=self.device))
        room = level_airframe_room(
            env.target.pose.p[:, None, :].expand(n, 4, 3), headings, grasp.expand(n, 3), boxes, env.proxy_points,
            env.proxy_radius,
        )
        best = headings.gather(1, room.argmax(1, keepdim=True))[:, 0]
        return torch.where(room[:, 0] >= TOP_DOWN_ROOM_M, planned, best)

    def grasp_target(self, tcp: torch.Tensor, pose: Pose | None = None, R: torch.Tensor | None = None) -> torch.Tensor:
        """Where the tool centre point grasps `(N, 3)` (`pick_grasp_target` of this env's object and plan). `pose` and
        its rotation matrix `R`: the object's, where the caller has them from this step's context."""
        pose = self.env.target.pose if pose is None else pose
        R = quat_wxyz_to_matrix(pose.q) if R is None else R
        env = self.env
        return pick_grasp_target(tcp, pose.p, R, self.heading, self.enclosed, env.target_grasp_point, env.target_height,
                                 env.target_half_extent, env.target_grasps_rim, env.platform.arm)

    def goal_features(self, ctx) -> GoalFeatures:
        return GoalFeatures(
            goal_point=self.grasp_target(ctx.tcp, ctx.object_pose, ctx.object_rotation),
            origin=ctx.tcp,
            heading_error=wrap_to_period(self.heading - ctx.state.yaw, self.heading_period),
            progress=ctx.object_bottom_z - self.rest_z,
        )

    def anchor(self, env_idx):
        pose = self.env.target.pose
        offset = self.env.target_grasp_point[env_idx]
        yaw = 2 * torch.atan2(pose.q[env_idx, 3], pose.q[env_idx, 0])
        c, s = torch.cos(yaw), torch.sin(yaw)
        return pose.p[env_idx] + torch.stack([c * offset[:, 0] - s * offset[:, 1], s * offset[:, 0] + c * offset[:, 1], offset[:, 2]], -1)

    def min_start_tcp_height(self, env_idx):
        return self.rest_z[env_idx] + self.env.target_height[env_idx] + START_ABOVE_OBJECT_M

    def update(self, ctx, mine):
        if self._update is None:
            self._update = pick_update_kernel(self.env.safety, self.device)
        out = PickUpdate(*self._update(ctx.object_bottom_z, self.rest_z, ctx.is_grasped, ctx.nontarget_force,
                                       self._every if mine is None else mine, self.hold_streak))
        self.hold_streak = out.hold_streak
        flags = [(FailureCause.COLLISION, out.fail_collision), (FailureCause.OBJECT_DROP, out.fail_drop)]
        signals = {"lift_height": out.lift, "is_lifted": out.lifted, "pick_hold_steps": self.hold_streak.clone()}
        return signals, out.success, flags

    def instruction(self, env):
        support = self.env.support_of(env, int(self.support_index[env]))
        return instruction("pick", obj=self.env.target_specs[env].name, where=support.name)

    def privileged_obs(self):
        return {"pick_rest_height": self.rest_z[:, None]}


class PickUpdate(NamedTuple):
    """The pick evaluator's tracker after one control step, its signals, success and failure flags `(N,)`."""

    hold_streak: torch.Tensor
    lift: torch.Tensor
    lifted: torch.Tensor
    success: torch.Tensor
    fail_collision: torch.Tensor
    fail_drop: torch.Tensor


def pick_update(object_bottom_z, rest_z, is_grasped, nontarget_force, mine, hold_streak, *,
                limits: SafetyLimits) -> PickUpdate:
    """One control step of the pick evaluator as a pure function of tensors (`(N,)`, no branch on a tensor value):
    the object's bottom height and its resting height, the grasp check, the largest non-target contact force, the
    envs where the pick is active (`mine`) and the hold streak, which advances only there."""
    lift = object_bottom_z - rest_z
    lifted = lift >= PICK_LIFT_M
    hold_streak = torch.where(mine, consecutive(hold_streak, is_grasped & lifted), hold_streak)
    return PickUpdate(
        hold_streak, lift, lifted,
        success=hold_streak >= PICK_HOLD_STEPS,
        fail_collision=nontarget_force > limits.collision_force_n,
        fail_drop=object_bottom_z < rest_z - limits.drop_margin_m,
    )


def _flat_pick_update(*tensors: torch.Tensor, limits: SafetyLimits) -> tuple[torch.Tensor, ...]:
    return tuple(pick_update(*tensors, limits=limits))


_SOURCES = [Path(__file__).resolve(), Path(__file__).resolve().parent.parent / "checks.py"]


def pick_update_kernel(limits: SafetyLimits, device: torch.device | str, compile: bool | None = None) -> Kernel:
    """The process's one `pick_update` kernel for `limits` on `device` (about a dozen small ops as one call on a
    CPU, compiled ahead of time and cached on disk)."""
    return shared_kernel(partial(_flat_pick_update, limits=limits), "pick_evaluator", limits, _SOURCES, device, compile)


@register_env("AeroPick-v1", max_episode_steps=400)
class AeroPickEnv(AeroSkillEnv):
    """**Task description.** Fly to the object, grasp it with the parallel gripper and lift it.

    **Randomizations.** Layout, materials and lights (per episode on one CPU env), the object class (unless
    `object=` is given), which support it stands on, its position and heading there, distractors, and the drone's
    start: level, 0.5-1 m from the object's grasp point, its tool centre point at least 0.15 m above the object.

    **Success conditions.** Grasped (both fingers >= 0.5 N) with the object at least 0.10 m above its resting height
    for 10 consecutive control steps. **Fails** on a non-target collision, an object drop, or the flight envelope
    (tilt, altitude, workspace). Episodes are 400 control steps (20 s), as in the spec's chained evaluation.
    """

    skill = "pick"

    def _make_evaluators(self):
        return [PickEvaluator(self)]

    def _sample_episode(self, env_idx):
        pick = self.evaluators[0]
        ok = pick.sample(env_idx)
        self.place_distractors(env_idx, self.target.pose.p[env_idx], self.setting.pick_supports)
        position, yaw, free = self.sample_start(env_idx, pick.anchor(env_idx), pick.min_start_tcp_height(env_idx))
        self.set_drone(env_idx, position, yaw)
        pick.begin(env_idx)
        for i in env_idx.tolist():
            self.instructions[i] = pick.instruction(i)
        return ok & free
