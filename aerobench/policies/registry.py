"""The policy registry: a name -> factory map filled by `@register_policy` at import time.

The package (`aerobench.policies`) imports the modules that register (builtin, learned, lerobot_policies) once this
module is loaded, so the registry is full wherever it is used and never imports what it registers (LeRobot's shape).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import torch

POLICIES: dict[str, Callable[..., Policy]] = {}


class Policy(Protocol):
    name: str

    def reset(self, env_idx: torch.Tensor) -> None:
        """Episodes start (again) in envs `env_idx`."""

    def act(self, obs) -> torch.Tensor:
        """`(N, A)` normalized actions for the current observation of every env."""


def register_policy(name: str):
    def decorate(factory):
        POLICIES[name] = factory
        return factory

    return decorate


def make_policy(name: str, env, checkpoint: str | None = None, **kwargs) -> Policy:
    """Build policy `name` for `env` (the unwrapped aerobench env); unknown names list the valid ones."""
    if name not in POLICIES:
        raise ValueError(f"unknown policy {name!r}; valid policies: {', '.join(sorted(POLICIES))}")
    return POLICIES[name](env, checkpoint=checkpoint, **kwargs)


def policy_needs_images(name: str, checkpoint: str | None = None) -> bool:
    """Whether policy `name` reads camera images (the runner then renders the three RGB-D cameras)."""
    if name not in POLICIES:
        raise ValueError(f"unknown policy {name!r}; valid policies: {', '.join(sorted(POLICIES))}")
    needs = getattr(POLICIES[name], "needs_images", None)
    return bool(needs(checkpoint)) if callable(needs) else False


def policy_training_starts(name: str, checkpoint: str | None):
    """The episode starts policy `name`'s checkpoint trained on (`provenance.TrainingStarts`; empty for policies
    that did not train on episodes, e.g. expert and random)."""
    from .provenance import TrainingStarts

    factory = POLICIES.get(name)
    starts = getattr(factory, "training_starts", None)
    return starts(checkpoint) if callable(starts) and checkpoint else TrainingStarts()


def policy_input_tier(name: str, checkpoints: list[str | None]) -> str:
    """The input tier (`aerobench.tiers`) of policy `name` with these checkpoints (one per skill stage): the widest
    of theirs (a row whose Pick is `vision` and whose Place is `privileged` is a `privileged` row)."""
    from .. import tiers

    if name not in POLICIES:
        raise ValueError(f"unknown policy {name!r}; valid policies: {', '.join(sorted(POLICIES))}")
    return tiers.widest(POLICIES[name].input_tier(c) for c in checkpoints or [None])


def check_policy_tier(name: str, checkpoints: list[str | None], tier: str) -> None:
    """Refuse (one line) to evaluate a policy that reads outside `tier` (`aerobench eval --inputs TIER`)."""
    from .. import tiers

    tiers.get_tier(tier)
    for checkpoint in checkpoints or [None]:
        features = getattr(POLICIES[name], "input_features", None)
        if callable(features):
            tiers.check_features(features(checkpoint), tier, f"--policy {name}" + (f" {checkpoint}" if checkpoint else ""))
        elif POLICIES[name].input_tier(checkpoint) not in (tier, tiers.NO_INPUTS):
            raise ValueError(f"--policy {name} reads the {POLICIES[name].input_tier(checkpoint)} tier, not {tier}")
