"""Place: set the held object down in the goal region, release it, back off and hover still (spec appendix)."""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path
from typing import NamedTuple

import torch
from mani_skill.utils.registration import register_env
from mani_skill.utils.structs import Pose

from ...accel import Kernel, shared_kernel
from ..checks import FailureCause, SafetyLimits, consecutive
from ..control.arm import arm_point_positions_body
from ..geometry import level_airframe_room
from ..observations import wrap_angle
from ..platforms import CONTROL_HZ
from ..tasks import instruction
from .base import AeroSkillEnv
from .evaluator import GoalFeatures, SkillEvaluator
from .markers import MarkerShape
from .starts import support_contains

PLACE_ALIGN_M = 0.05  # horizontal alignment tolerance: the event t_o
PLACE_GOAL_RADIUS_M = 0.10  # goal region around the goal point
PLACE_REST_TOLERANCE_M = 0.02  # "resting height": object bottom this close to the goal support's surface
OBJECT_STILL_MPS = 0.05
GRIPPER_OPEN_MARGIN_M = 0.01  # open: the pads at least this much wider than the object's grasp width ...
GRIPPER_FULLY_OPEN_SLACK_M = 0.003  # ... or fully open (the master chef can leaves only 8 mm)
PLACE_CLEARANCE_M = 0.27  # spec: gripper more than 0.27 m from the object
PLATFORM_STABLE_MPS = 0.025  # spec: platform speed below 0.025 m/s ...
PLATFORM_STABLE_STEPS = 20  # ... for 20 consecutive control steps
HOVER_ABOVE_GOAL_M = 0.05  # the anchor: the tool centre point a little above its placed position
SET_DOWN_OBSERVED_S = 1.0  # the task state's set-down time saturates here (the expert releases after 0.45 s)
GOAL_MARKER = MarkerShape("disc", radius_m=PLACE_GOAL_RADIUS_M, thickness_m=0.002)  # the goal region, drawn on its support
# The arm holds the object 0.24-0.48 m ahead of the airframe, so over a goal by a wall the airframe may stand in the
# wall at the heading the place begins with (two fridge-chain places flew the airframe into it). Where the airframe
# would stand in the scene at the release (its proxy points' clearance below PLACE_ROOM_M), the place's heading is the
# one of PLACE_HEADINGS (turns of the heading it begins with) with the most room; the policy reads it as the heading
# error. Everywhere else the heading is kept, as before.
PLACE_ROOM_M = 0.0
PLACE_HEADINGS = 8
RELEASE_COLUMN_M = (0.0, 0.15)  # the release and the top of the descent onto it, above the release


def carried_arm_pose(arm, after_enclosed_pick: torch.Tensor | None, n: int, device) -> torch.Tensor:
    """`(N, 3)` the arm pose an object is carried and set down in: folded under the airframe (`carry_pose_rad`)
    after a pick that reached into an enclosure (`after_enclosed_pick`), the top-down pose after a top-down pick, the
    working pose where the object started in the jaws (a Place start: None). Both carry poses keep the forearm's
    angle of the grasp, so the object stays upright."""
    working = torch.tensor(arm.working_pose_rad, dtype=torch.float32, device=device).expand(n, 3)
    if after_enclosed_pick is None:
        return working
    carry = torch.tensor(arm.carry_pose_rad, dtype=torch.float32, device=device)
    top_down = torch.tensor(arm.top_down_pose_rad, dtype=torch.float32, device=device)
    return torch.where(after_enclosed_pick[:, None], carry, top_down)


class PlaceEvaluator(SkillEvaluator):
    skill = "place"
    marker = GOAL_MARKER

    def __init__(self, env, where=(), after_pick=None):
        super().__init__(env, where)
        self.after_pick = after_pick  # the chain's pick evaluator that grasped the object (None: a Place start)
        self.kinds = self.where or env.setting.place_supports
        self.goal = torch.zeros(self.n, 3, device=self.device)
        self.goal_support = self.zeros(torch.long)
        self.released = self.zeros(torch.bool)
        self.stable_streak = self.zeros(torch.long)
        self.set_down_streak = self.zeros(torch.long)
        self.unsupported_streak = self.zeros(torch.long)
        self.collision_impulse = self.zeros()
        self.heading = self.zeros()  # chosen at the skill's start (`place_heading`) and held: the object keeps its
        # place in the jaws
        self._update: Kernel | None = None  # the compiled `place_update`, made at the first update
        self._every = torch.ones(self.n, dtype=torch.bool, device=self.device)  # `mine` in a single-skill env

    def sample_goal(self, env_idx: torch.Tensor, avoid_support: torch.Tensor | None = None) -> torch.Tensor:
        """A goal point on a destination support (`(M,)` ok: the layout has one)."""
        env = self.env
        index, ok = env.sample_supports(env_idx, self.kinds)
        self.goal[env_idx] = env.sample_on_support(env_idx, index, env.target_radius[env_idx] + 0.05)
        self.goal_support[env_idx] = index
        return ok

    def begin(self, env_idx):
        self.heading[env_idx] = self.place_heading(env_idx)
        self.released[env_idx] = False
        self.stable_streak[env_idx] = 0
        self.set_down_streak[env_idx] = 0
        self.unsupported_streak[env_idx] = 0
        self.collision_impulse[env_idx] = 0.0

    def place_heading(self, env_idx: torch.Tensor) -> torch.Tensor:
        """`(M,)` the heading to place at: the one the skill begins with, except on the arm platform where its airframe
        would keep less than PLACE_ROOM_M from the scene at the release (or the descent's top) with the object on the
        goal; there the turn of it with the most room."""
        env, arm = self.env, self.env.platform.arm
        yaw = env.agent.airframe_state().yaw[env_idx]
        if arm is None:  # the gripper holds the object under the airframe's centre: no heading stands it elsewhere
            return yaw
        m = len(env_idx)
        turns = torch.arange(PLACE_HEADINGS, device=self.device) * (2 * math.pi / PLACE_HEADINGS)
        headings = yaw[:, None] + turns  # (M, K)
        enclosed = None if self.after_pick is None else self.after_pick.enclosed[env_idx]
        grasp_body = arm_point_positions_body(carried_arm_pose(arm, enclosed, m, self.device), arm)["grasp"]
        release = self.goal[env_idx].clone()
        release[:, 2] += env.target_grasp_point[env_idx, 2]  # the grasp point with the object on the goal
        boxes = env.obstacle_boxes(env_idx)
        lift = torch.tensor([0.0, 0.0, 1.0], device=self.device)
        room = torch.stack([
            level_airframe_room((release + up * lift)[:, None].expand(m, PLACE_HEADINGS, 3), headings, grasp_body,
                                boxes, env.proxy_points, env.proxy_radius)
            for up in RELEASE_COLUMN_M
        ]).min(0).values
        best = headings.gather(1, room.argmax(1, keepdim=True))[:, 0]
        return torch.where(room[:, 0] >= PLACE_ROOM_M, yaw, wrap_angle(best))

    def anchor(self, env_idx):
        lift = self.env.target_grasp_point[env_idx, 2] + HOVER_ABOVE_GOAL_M
        return self.goal[env_idx] + torch.stack([torch.zeros_like(lift), torch.zeros_like(lift), lift], -1)

    def outside_destination(self, env_idx: torch.Tensor, tcp: torch.Tensor) -> torch.Tensor:
        """Eligible held state: the object (under the tool centre point) is outside the destination support."""
        m, k = tcp.shape[:2]
        rows = env_idx.repeat_interleave(k)
        inside = self.env.inside_support(rows, self.goal_support[rows], tcp.reshape(-1, 3)[:, :2], margin=-0.05)
        return ~inside.reshape(m, k)

    def update(self, ctx, mine):
        env = self.env
        if self._update is None:
            self._update = place_update_kernel(self._update_law(), self.device)
        goal_support = env.supports[torch.arange(self.n, device=self.device), self.goal_support]
        out = PlaceUpdate(*self._update(
            ctx.object_pose.p, ctx.object_bottom_z, ctx.object_velocity, ctx.is_supported, ctx.is_upright,
            ctx.is_grasped, ctx.is_grasp_held, ctx.gripper_opening, ctx.tcp, ctx.grasp_point, ctx.speed,
            ctx.nontarget_force, self.goal, goal_support, env.target_grasp_width, self._every if mine is None else mine,
            self.set_down_streak, self.released, self.stable_streak, self.unsupported_streak, self.collision_impulse,
        ))
        self.set_down_streak, self.released, self.stable_streak = out.set_down_streak, out.released, out.stable_streak
        self.unsupported_streak, self.collision_impulse = out.unsupported_streak, out.collision_impulse
        flags = [
            (FailureCause.COLLISION_FORCE, out.fail_collision),
            (FailureCause.OBJECT_DROP, out.fail_drop),
            (FailureCause.UNSUPPORTED_RELEASE, out.fail_unsupported),
        ]
        signals = {
            "goal_distance": out.goal_distance,
            "is_aligned": out.is_aligned,
            "is_support_contact": out.support_contact,
            "is_set_down": out.support_contact,
            "set_down_steps": self.set_down_streak.clone(),
            "is_placed": out.placed,
            "is_gripper_open": out.gripper_open,
            "is_released": out.release,
            "release_registered": self.released.clone(),
            "is_gripper_clear": out.clear,
            "platform_stable_steps": self.stable_streak.clone(),
            "collision_impulse": self.collision_impulse.clone(),
        }
        return signals, out.success, flags

    def _update_law(self) -> PlaceUpdateLaw:
        return PlaceUpdateLaw(self.env.safety, self.env.platform.gripper.max_opening_m - GRIPPER_FULLY_OPEN_SLACK_M)

    def goal_features(self, ctx) -> GoalFeatures:
        return GoalFeatures(
            goal_point=self.goal,
            origin=ctx.object_pose.p,
            heading_error=wrap_angle(self.heading - ctx.state.yaw),
            progress=self.set_down_time(),
        )

    def set_down_time(self) -> torch.Tensor:
        """`(N,)` seconds the goal support has carried the object without a break, capped: what a gripper's force
        sensing reports as the load leaving the fingers. The expert releases on it, so a policy can too."""
        return torch.clamp(self.set_down_streak.float() / CONTROL_HZ, max=SET_DOWN_OBSERVED_S)

    def instruction(self, env):
        support = self.env.support_of(env, int(self.goal_support[env]))
        return instruction("place", obj=self.env.target_specs[env].name, where=support.name)

    def privileged_obs(self):
        return {"place_goal": self.goal.clone()}

    def marker_position(self, env_idx):
        return self.goal[env_idx], torch.ones(len(env_idx), dtype=torch.bool, device=self.device)


class PlaceUpdateLaw(NamedTuple):
    """What fixes `place_update` besides its tensors (hashable: a compiled kernel's key)."""

    limits: SafetyLimits
    wide_open_m: float  # the pads' opening that counts as fully open


class PlaceUpdate(NamedTuple):
    """The place evaluator's trackers after one control step, its signals, success and failure flags `(N,)`."""

    set_down_streak: torch.Tensor
    released: torch.Tensor
    stable_streak: torch.Tensor
    unsupported_streak: torch.Tensor
    collision_impulse: torch.Tensor
    goal_distance: torch.Tensor
    is_aligned: torch.Tensor
    support_contact: torch.Tensor
    placed: torch.Tensor
    gripper_open: torch.Tensor
    release: torch.Tensor
    clear: torch.Tensor
    success: torch.Tensor
    fail_collision: torch.Tensor
    fail_drop: torch.Tensor
    fail_unsupported: torch.Tensor


def place_update(
    obj, object_bottom_z, object_velocity, is_supported, is_upright, is_grasped, is_grasp_held, gripper_opening,
    tcp, grasp_point, speed, nontarget_force, goal, goal_support, grasp_width, mine,
    set_down_streak, released, stable_streak, unsupported_streak, collision_impulse, *, law: PlaceUpdateLaw,
) -> PlaceUpdate:
    """One control step of the place evaluator as a pure function of tensors (`(N, ...)`, no branch on a tensor
    value): the step context's object, grasp and airframe signals, the goal and its support's row, the object's
    grasp width, the envs where the place is active (`mine`) and the trackers; the trackers advance only there."""
    limits = law.limits

    def keep(new, old):
        return torch.where(mine, new, old)

    horizontal = torch.linalg.norm(obj[:, :2] - goal[:, :2], dim=-1)
    at_height = (object_bottom_z - goal[:, 2]).abs() < PLACE_REST_TOLERANCE_M
    support_contact = is_supported & at_height & support_contains(goal_support, obj[:, :2])
    set_down_streak = keep(consecutive(set_down_streak, support_contact), set_down_streak)
    object_still = torch.linalg.norm(object_velocity, dim=-1) < OBJECT_STILL_MPS
    placed = (horizontal < PLACE_GOAL_RADIUS_M) & is_upright & object_still & support_contact
    gripper_open = gripper_opening > torch.clamp(grasp_width + GRIPPER_OPEN_MARGIN_M, max=law.wide_open_m)
    release = support_contact & ~is_grasp_held & gripper_open
    released = keep(released | release, released)
    clear = torch.linalg.norm(tcp - grasp_point, dim=-1) > PLACE_CLEARANCE_M
    stable_streak = keep(consecutive(stable_streak, speed < PLATFORM_STABLE_MPS), stable_streak)
    success = placed & gripper_open & released & clear & (stable_streak >= PLATFORM_STABLE_STEPS)
    loose = ~is_grasped & ~is_supported & ~released
    unsupported_streak = keep(consecutive(unsupported_streak, loose), unsupported_streak)
    hard = nontarget_force * (nontarget_force > limits.collision_force_n)
    collision_impulse = keep(collision_impulse + hard / CONTROL_HZ, collision_impulse)
    return PlaceUpdate(
        set_down_streak, released, stable_streak, unsupported_streak, collision_impulse,
        goal_distance=horizontal,
        is_aligned=horizontal < PLACE_ALIGN_M,
        support_contact=support_contact,
        placed=placed,
        gripper_open=gripper_open,
        release=release,
        clear=clear,
        success=success,
        fail_collision=collision_impulse > limits.collision_impulse_budget_ns,
        fail_drop=~is_grasped & (object_bottom_z < goal[:, 2] - limits.drop_margin_m),
        fail_unsupported=unsupported_streak >= limits.unsupported_release_steps,
    )


def _flat_place_update(*tensors: torch.Tensor, law: PlaceUpdateLaw) -> tuple[torch.Tensor, ...]:
    return tuple(place_update(*tensors, law=law))


_HERE = Path(__file__).resolve().parent
_SOURCES = [_HERE / "place.py", _HERE / "starts.py", _HERE.parent / "checks.py", _HERE.parent / "platforms.py"]


def place_update_kernel(law: PlaceUpdateLaw, device: torch.device | str, compile: bool | None = None) -> Kernel:
    """The process's one `place_update` kernel for `law` on `device` (compiled once per process; on a CPU ahead of
    time, cached on disk)."""
    return shared_kernel(partial(_flat_place_update, law=law), "place_evaluator", law, _SOURCES, device, compile)


def put_object_in_gripper(env, env_idx: torch.Tensor, drone_yaw: torch.Tensor) -> None:
    """Hold the target between the pads: grasp point at the tool centre point, object x along the closing axis."""
    tcp = env.agent.tcp_pose.p[env_idx]
    yaw = drone_yaw + math.pi / 2  # body y (the closing axis) = object x
    c, s = torch.cos(yaw), torch.sin(yaw)
    g = env.target_grasp_point[env_idx]
    bottom = tcp - torch.stack([c * g[:, 0] - s * g[:, 1], s * g[:, 0] + c * g[:, 1], g[:, 2]], -1)
    q = torch.stack([torch.cos(yaw / 2), torch.zeros_like(yaw), torch.zeros_like(yaw), torch.sin(yaw / 2)], -1)
    env.target.set_pose(Pose.create_from_pq(p=bottom, q=q))
    env.target.set_linear_velocity(torch.zeros(len(env_idx), 3, device=env.device))
    env.target.set_angular_velocity(torch.zeros(len(env_idx), 3, device=env.device))


def carried_object_points(env, env_idx: torch.Tensor) -> torch.Tensor:
    """Points of a held object relative to the tool centre point `(M, 5, 3)`: bottom centre and footprint."""
    g = env.target_grasp_point[env_idx]
    r = env.target_radius[env_idx]
    zero = torch.zeros_like(r)
    bottom = -g[:, 2]
    pts = [torch.stack([zero, zero, bottom], -1)]
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        pts.append(torch.stack([dx * r, dy * r, bottom], -1))
    return torch.stack(pts, dim=1)


@register_env("AeroPlace-v1", max_episode_steps=1000)
class AeroPlaceEnv(AeroSkillEnv):
    """**Task description.** Carry the held object to the goal, set it down there, open the gripper, back off and
    hover still.

    **Randomizations.** Layout, materials, lights, object class (unless `object=`), the destination support and the
    goal point on it, distractors, and the start: an eligible held state (object pinched at the tool centre point,
    outside the destination support), the tool centre point 0.5-1 m from the point above the goal.

    **Success conditions** (spec): object in the goal region (10 cm), upright, still and resting on the destination
    support; gripper open; release registered; gripper more than 0.27 m from the object; platform speed below
    0.025 m/s for 20 consecutive control steps; no latched failure. **Fails** on the collision-force budget, flight
    envelope, object drop or an unsupported release. Episodes are 1000 control steps (spec's place budget).
    """

    skill = "place"

    def _make_evaluators(self):
        return [PlaceEvaluator(self)]

    def _sample_episode(self, env_idx):
        place = self.evaluators[0]
        ok = place.sample_goal(env_idx)
        self.place_distractors(env_idx, place.goal[env_idx], self.setting.place_supports)
        height = place.goal[env_idx, 2] + self.target_height[env_idx] + 0.10
        position, yaw, free = self.sample_start(
            env_idx,
            place.anchor(env_idx),
            height + self.target_grasp_point[env_idx, 2],
            carried_points=carried_object_points(self, env_idx),
            reject=lambda tcp: ~place.outside_destination(env_idx, tcp),
        )
        self.set_drone(env_idx, position, yaw, finger_half_opening=self.target_grasp_width[env_idx] / 2)
        put_object_in_gripper(self, env_idx, yaw)
        self.starts_held[env_idx] = True
        place.begin(env_idx)
        for i in env_idx.tolist():
            self.instructions[i] = place.instruction(i)
        return ok & free
