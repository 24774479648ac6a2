"""Nav: fly the airframe to a target position and settle there without collision."""

from __future__ import annotations

import numpy as np
import torch
from mani_skill.utils.registration import register_env

from ..checks import FailureCause, consecutive
from ..observations import wrap_angle
from ..tasks import instruction
from .base import AeroSkillEnv
from .evaluator import GoalFeatures, SkillEvaluator
from .markers import MarkerShape

NAV_REACH_M = 0.10  # airframe centre within this distance of the target
NAV_SETTLE_MPS = 0.05
NAV_SETTLE_STEPS = 10
LOST_GRASP_STEPS = 5  # carrying: this many control steps without a grasp is a dropped object
TARGET_MARKER = MarkerShape("sphere", radius_m=0.04)  # a ball at the target, well inside the 0.10 m reach


class NavEvaluator(SkillEvaluator):
    """Target: a named nav point of the layout (`where=("the building entrance",)`), a random one, or a point set
    by the chain (`set_target`, e.g. above the next placement goal). `carrying`: the drone holds the target object."""

    skill = "nav"
    marker = TARGET_MARKER

    def __init__(self, env, where=(), carrying: bool = False):
        super().__init__(env, where)
        self.carrying = carrying
        self.target = torch.zeros(self.n, 3, device=self.device)
        self.target_names = [""] * self.n
        self.named = self.zeros(torch.bool)  # the target is one of the layout's named nav points (its marker shows)
        self.settle_streak = self.zeros(torch.long)
        self.lost_streak = self.zeros(torch.long)
        self.heading = self.zeros()  # held from the skill's start

    def sample_target(self, env_idx: torch.Tensor) -> torch.Tensor:
        ok = torch.ones(len(env_idx), dtype=torch.bool, device=self.device)
        for row, i in enumerate(env_idx.tolist()):
            points = self.env.layouts[i].nav_points
            names = [n for n in self.where if n in points] if self.where else sorted(points)
            if not names:
                ok[row] = False
                continue
            name = names[int(torch.randint(len(names), (1,), generator=self.env.episode_rng[i]))]
            self.target[i] = torch.tensor(points[name], device=self.device)
            self.target_names[i] = name
        self.named[env_idx] = ok
        return ok

    def set_target(self, env_idx: torch.Tensor, target: torch.Tensor, names: list[str]) -> None:
        """A target the chain sets (e.g. above the next placement goal, whose own marker shows where it is)."""
        self.target[env_idx] = target
        self.named[env_idx] = False
        for i, name in zip(env_idx.tolist(), names):
            self.target_names[i] = name

    def begin(self, env_idx):
        self.heading[env_idx] = self.env.agent.airframe_state().yaw[env_idx]
        self.settle_streak[env_idx] = 0
        self.lost_streak[env_idx] = 0

    def anchor(self, env_idx):
        return self.target[env_idx]

    def update(self, ctx, mine):
        distance = torch.linalg.norm(ctx.state.position - self.target, dim=-1)
        reached = distance < NAV_REACH_M
        settled = reached & (ctx.speed < NAV_SETTLE_MPS)
        self.settle_streak = self.keep(mine, consecutive(self.settle_streak, settled), self.settle_streak)
        success = self.settle_streak >= NAV_SETTLE_STEPS
        flags = [(FailureCause.COLLISION, ctx.nontarget_force > self.env.safety.collision_force_n)]
        if self.carrying:
            self.lost_streak = self.keep(mine, consecutive(self.lost_streak, ~ctx.is_grasped), self.lost_streak)
            flags.append((FailureCause.OBJECT_DROP, self.lost_streak >= LOST_GRASP_STEPS))
        signals = {"nav_distance": distance, "is_nav_reached": reached, "nav_settle_steps": self.settle_streak.clone()}
        return signals, success, flags

    def goal_features(self, ctx) -> GoalFeatures:
        return GoalFeatures(
            goal_point=self.target,
            origin=ctx.state.position,
            heading_error=wrap_angle(self.heading - ctx.state.yaw),
            progress=torch.zeros_like(self.heading),
        )

    def instruction(self, env):
        name = self.target_names[env]
        return instruction("nav", target=f"the marker at {name}" if bool(self.named[env]) else name)

    def privileged_obs(self):
        return {"nav_target": self.target.clone()}

    def marker_position(self, env_idx):
        return self.target[env_idx], self.named[env_idx]


@register_env("AeroNav-v1", max_episode_steps=600)
class AeroNavEnv(AeroSkillEnv):
    """**Task description.** Fly to a named place of the scene ("fly to the kitchen") and hover there.

    **Randomizations.** Layout, materials, lights, the target (one of the layout's named nav points) and the start:
    level, 0.5-1 m from the target, collision-free.

    **Success conditions.** Airframe centre within 0.10 m of the target at below 0.05 m/s for 10 consecutive control
    steps. **Fails** on a collision or the flight envelope. Episodes are 600 control steps (30 s).
    """

    skill = "nav"
    uses_object = False

    def _make_evaluators(self):
        return [NavEvaluator(self)]

    def _sample_episode(self, env_idx):
        nav = self.evaluators[0]
        ok = nav.sample_target(env_idx)
        position, yaw, free = self.sample_start(
            env_idx, nav.anchor(env_idx), torch.full((len(env_idx),), -np.inf, device=self.device), from_airframe=True
        )
        self.set_drone(env_idx, position, yaw)
        nav.begin(env_idx)
        for i in env_idx.tolist():
            self.instructions[i] = nav.instruction(i)
        return ok & free
