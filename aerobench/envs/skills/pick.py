"""Pick: grasp the object and hold it above its lift threshold (spec appendix, Pick completion check)."""

from __future__ import annotations

import math

import torch
from mani_skill.utils.registration import register_env

from ..checks import FailureCause, consecutive
from ..control.so3 import quat_wxyz_to_matrix
from ..observations import wrap_to_period
from ..tasks import instruction
from .base import AeroSkillEnv
from .evaluator import GoalFeatures, SkillEvaluator
from .starts import SUPPORT_KINDS

PICK_LIFT_M = 0.10  # lift threshold above the instance's own resting height (so it differs per instance)
PICK_HOLD_STEPS = 10  # consecutive control steps grasped and lifted (0.5 s)
START_ABOVE_OBJECT_M = 0.15  # the tool centre point starts at least this far above the object's top
ROUND_SHAPES = ("cylinder", "bowl")  # round about z: any heading on the room axes grasps them
# Supports inside a fixture, open only on its front (the support's +x): the grasp heading points in through the front,
# and a box stands with a grasp axis along it (the fridge's side walls leave no other way in).
ENCLOSED_KINDS = ("fridge_shelf",)
ENCLOSED_YAW_NOISE_RAD = 0.15


def grasp_heading(object_yaw: torch.Tensor, current_yaw: torch.Tensor, is_round: torch.Tensor) -> torch.Tensor:
    """The heading that puts the closing axis (body y) along the object's x axis, the nearer of the two; objects that
    are round about z keep the current heading rounded to the room axes (supports are fitted for it)."""
    across = current_yaw + wrap_to_period(object_yaw + math.pi / 2 - current_yaw, math.pi)
    axis_aligned = current_yaw + wrap_to_period(-current_yaw, math.pi / 2)
    return torch.where(is_round, axis_aligned, across)


class PickEvaluator(SkillEvaluator):
    skill = "pick"

    def __init__(self, env, where=()):
        super().__init__(env, where)
        self.kinds = self.where or env.setting.pick_supports
        self.rest_z = self.zeros()
        self.support_index = self.zeros(torch.long)
        self.hold_streak = self.zeros(torch.long)
        specs = env.target_specs
        self.is_round = torch.tensor([s.shape in ROUND_SHAPES for s in specs], dtype=torch.bool, device=self.device)
        self.heading_period = torch.where(self.is_round, math.pi / 2, math.pi)
        self.heading = self.zeros()  # the grasp heading planned when the skill starts
        self.inward = self.zeros()  # enclosed supports: the heading through the fixture's front
        self.enclosed = self.zeros(torch.bool)

    def sample(self, env_idx: torch.Tensor) -> torch.Tensor:
        """Put the target upright at a random spot of a random source support; `(M,)` whether one existed."""
        env = self.env
        index, ok = env.sample_supports(env_idx, self.kinds)
        bottom = env.sample_on_support(env_idx, index, env.target_radius[env_idx] + 0.04)
        row = env.supports[env_idx, index]
        enclosed_ids = torch.tensor([SUPPORT_KINDS.index(k) for k in ENCLOSED_KINDS], device=self.device)
        enclosed = (row[:, 6][:, None] == enclosed_ids).any(-1)
        inward = row[:, 5] + math.pi
        yaw = (torch.rand(len(env_idx), device=self.device) * 2 - 1) * math.pi
        # the closing axis (body y) lies along the object's x: x across the way in
        noise = (torch.rand(len(env_idx), device=self.device) * 2 - 1) * ENCLOSED_YAW_NOISE_RAD
        yaw = torch.where(enclosed, inward - math.pi / 2 + noise, yaw)
        self.enclosed[env_idx], self.inward[env_idx] = enclosed, inward
        env.place_object(env.target, env_idx, bottom, yaw)
        self.support_index[env_idx] = index
        self.rest_z[env_idx] = bottom[:, 2]
        return ok

    def begin(self, env_idx):
        pose = self.env.target.pose
        self.rest_z[env_idx] = pose.p[env_idx, 2]
        self.hold_streak[env_idx] = 0
        object_yaw = 2 * torch.atan2(pose.q[:, 3], pose.q[:, 0])
        reference = torch.where(self.enclosed, self.inward, self.env.agent.airframe_state().yaw)
        planned = grasp_heading(object_yaw, reference, self.is_round)
        planned = torch.where(self.enclosed & self.is_round, self.inward, planned)  # straight in through the front
        self.heading[env_idx] = planned[env_idx]

    def grasp_target(self, tcp: torch.Tensor) -> torch.Tensor:
        """Where the tool centre point grasps `(N, 3)`: the object's planned grasp point; for the bowl, the rim point
        whose radial direction is the closing axis (body y) of the planned heading, on the side nearer `tcp`."""
        pose = self.env.target.pose
        R = quat_wxyz_to_matrix(pose.q)
        planned = pose.p + (R @ self.env.target_grasp_point[..., None])[..., 0]
        zero = torch.zeros_like(self.heading)
        radial = torch.stack([-torch.sin(self.heading), torch.cos(self.heading), zero], -1)
        side = torch.sign((radial * (tcp - pose.p)).sum(-1, keepdim=True) + 1e-9)
        g = self.env.target_grasp_point  # a rim grasp's pinch point: rim radius (x) and height above the bottom (z)
        rim = pose.p + g[:, :1] * side * radial + torch.stack([zero, zero, g[:, 2]], -1)
        return torch.where(self.env.target_grasps_rim[:, None], rim, planned)

    def goal_features(self, ctx) -> GoalFeatures:
        return GoalFeatures(
            goal_pos=self.grasp_target(ctx.tcp) - ctx.tcp,
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
        lift = ctx.object_bottom_z - self.rest_z
        lifted = lift >= PICK_LIFT_M
        self.hold_streak = self.keep(mine, consecutive(self.hold_streak, ctx.is_grasped & lifted), self.hold_streak)
        success = self.hold_streak >= PICK_HOLD_STEPS
        limits = self.env.safety
        flags = [
            (FailureCause.COLLISION, ctx.nontarget_force > limits.collision_force_n),
            (FailureCause.OBJECT_DROP, ctx.object_bottom_z < self.rest_z - limits.drop_margin_m),
        ]
        signals = {"lift_height": lift, "is_lifted": lifted, "pick_hold_steps": self.hold_streak.clone()}
        return signals, success, flags

    def instruction(self, env):
        support = self.env.support_of(env, int(self.support_index[env]))
        return instruction("pick", obj=self.env.target_specs[env].name, where=support.name)

    def privileged_obs(self):
        return {"pick_rest_height": self.rest_z[:, None]}


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
