"""Pick: grasp the object and hold it above its lift threshold (spec appendix, Pick completion check)."""

from __future__ import annotations

import math

import torch
from mani_skill.utils.registration import register_env

from ..checks import FailureCause, consecutive
from ..tasks import instruction
from .base import AeroSkillEnv
from .evaluator import SkillEvaluator

PICK_LIFT_M = 0.10  # lift threshold above the instance's own resting height (so it differs per instance)
PICK_HOLD_STEPS = 10  # consecutive control steps grasped and lifted (0.5 s)
START_ABOVE_OBJECT_M = 0.15  # the tool centre point starts at least this far above the object's top


class PickEvaluator(SkillEvaluator):
    skill = "pick"

    def __init__(self, env, where=()):
        super().__init__(env, where)
        self.kinds = self.where or env.setting.pick_supports
        self.rest_z = self.zeros()
        self.support_index = self.zeros(torch.long)
        self.hold_streak = self.zeros(torch.long)

    def sample(self, env_idx: torch.Tensor) -> torch.Tensor:
        """Put the target upright at a random spot of a random source support; `(M,)` whether one existed."""
        env = self.env
        index, ok = env.sample_supports(env_idx, self.kinds)
        bottom = env.sample_on_support(env_idx, index, env.target_radius[env_idx] + 0.04)
        yaw = (torch.rand(len(env_idx), device=self.device) * 2 - 1) * math.pi
        env.place_object(env.target, env_idx, bottom, yaw)
        self.support_index[env_idx] = index
        self.rest_z[env_idx] = bottom[:, 2]
        return ok

    def begin(self, env_idx):
        self.rest_z[env_idx] = self.env.target.pose.p[env_idx, 2]
        self.hold_streak[env_idx] = 0

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
