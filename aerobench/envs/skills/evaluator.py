"""The interface every skill's evaluator implements (pick, place, nav, open/close).

An evaluator owns one skill's goal and per-env trackers (streaks, latched events). The env calls `update` once per
control step with the shared `StepContext` and a mask of the envs where this skill is the active one; trackers only
advance there, so the same evaluator serves a single-skill env and one stage of a sequential env.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ..checks import FailureCause
from .markers import MarkerShape

Flags = list[tuple[FailureCause, torch.Tensor]]


@dataclass
class GoalFeatures:
    """One skill's part of the task state (`observations.TASK_STATE_FIELDS`), `(N, ...)` for every env."""

    goal_point: torch.Tensor  # (N, 3) the goal, world frame (its room decides the doorway field)
    origin: torch.Tensor  # (N, 3) the point it is for (TCP, object bottom centre, airframe centre)
    heading_error: torch.Tensor  # (N,) rad, wrapped to the goal heading's symmetry
    progress: torch.Tensor  # (N,)
    # (N,) bool: the tactile grasp confirmation where the skill grasps something other than the target object (the
    # handle of Open / Close); None: the target object's (`is_grasp_confirmed`)
    grasp_confirmed: torch.Tensor | None = None

    @property
    def goal_pos(self) -> torch.Tensor:
        """`(N, 3)` the goal minus the point it is for."""
        return self.goal_point - self.origin


class SkillEvaluator:
    skill: str = ""
    marker: MarkerShape | None = None  # the visual-only marker that shows this skill's goal (`markers`); None: none

    def __init__(self, env, where: tuple[str, ...] = ()):
        self.env = env
        self.where = tuple(where)
        self.device = env.device
        self.n = env.num_envs

    def zeros(self, dtype=torch.float32) -> torch.Tensor:
        return torch.zeros(self.n, dtype=dtype, device=self.device)

    def begin(self, env_idx: torch.Tensor) -> None:
        """This skill becomes active for `env_idx` (episode start, or the previous chain stage succeeded)."""

    def anchor(self, env_idx: torch.Tensor) -> torch.Tensor:
        """The point `(M, 3)` the drone starts 0.5-1 m from when this skill starts an episode."""
        raise NotImplementedError

    def update(self, ctx, mine: torch.Tensor | None) -> tuple[dict[str, torch.Tensor], torch.Tensor, Flags]:
        """(signals, success `(N,)`, failure flags in priority order) for this control step; `mine` masks the envs
        where this skill is active, None where it is active in every env (a single-skill env)."""
        raise NotImplementedError

    def goal_features(self, ctx) -> GoalFeatures:
        """The relative goal geometry a state-based policy reads while this skill is active."""
        raise NotImplementedError

    def instruction(self, env: int) -> str:
        raise NotImplementedError

    def marker_position(self, env_idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Where this skill's marker stands in the envs `env_idx` `(M, 3)`, and whether it is shown there `(M,)`
        (read once the episode's goals are sampled)."""
        raise NotImplementedError(f"{type(self).__name__} has a marker but no marker_position")

    def privileged_obs(self) -> dict[str, torch.Tensor]:
        """Goal information for state observations (never part of the policy-facing camera/proprio inputs)."""
        return {}

    @staticmethod
    def keep(mine: torch.Tensor | None, new: torch.Tensor, old: torch.Tensor) -> torch.Tensor:
        """Advance a tracker only where this skill is active (`mine` None: in every env)."""
        if mine is None:
            return new
        m = mine.view(-1, *([1] * (new.dim() - 1)))
        return torch.where(m, new, old)
