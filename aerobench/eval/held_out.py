"""Which evaluation starts a learned policy already saw in training.

The evaluator asks the policy what it trained on (`policies.registry.policy_training_starts`; each skill's checkpoint
of a `pick=A,place=B` mapping) and counts its planned episodes among those starts, so results say whether they are
held out (`policies.provenance` explains how checkpoints carry their training starts).
"""

from __future__ import annotations

from ..envs.tasks import TaskSetting
from ..policies.provenance import TrainingStarts
from ..policies.registry import policy_training_starts
from ..rollout.runner import EpisodePlan


def training_starts(policy: str, checkpoints: dict[str, str | None]) -> TrainingStarts:
    """Everything the policy's checkpoints (`chained.split_checkpoints`' mapping: one folder, or each skill's for a
    `pick=A,place=B` mapping) trained on."""
    out = TrainingStarts()
    for path in checkpoints.values():
        if path:
            out.add(policy_training_starts(policy, path))
    return out


def plan_start_skill(setting: TaskSetting, skill: str) -> str:
    """The skill an episode starts with: itself, or a chain's first stage (its start is that skill's start)."""
    return setting.chains[skill][0].skill if skill in setting.chains else skill


def seen_in_training(setting: TaskSetting, plans: list[EpisodePlan], starts: TrainingStarts) -> list[int]:
    """Indices of the planned evaluation episodes whose start the policy trained on."""
    return [p.index for p in plans
            if starts.seen(setting.name, plan_start_skill(setting, p.skill), p.object, p.seed)]
