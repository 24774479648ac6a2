"""The policies that need no training: the privileged expert and a uniform random policy."""

from __future__ import annotations

import torch

from .. import tiers
from ..expert import ExpertController
from .registry import register_policy


@register_policy("expert")
class ExpertPolicy:
    """The privileged hybrid expert (reads simulator state, not the observation)."""

    name = "expert"
    input_tier = staticmethod(lambda checkpoint=None: tiers.PRIVILEGED.name)  # it acts on the simulator's state

    def __init__(self, env, checkpoint: str | None = None, **_):
        if checkpoint:
            raise ValueError("the expert policy takes no --checkpoint")
        self.controller = ExpertController(env)

    def reset(self, env_idx):
        self.controller.reset(env_idx)

    def act(self, obs):
        return self.controller.act()

    def phase(self) -> torch.Tensor:
        return self.controller.phase()

    def infeasible(self) -> torch.Tensor:
        return self.controller.infeasible()


@register_policy("random")
class RandomPolicy:
    input_tier = staticmethod(lambda checkpoint=None: tiers.NO_INPUTS)  # it reads nothing
    """Uniform random actions in [-1, 1], each held for `hold` control steps (seeded)."""

    name = "random"

    def __init__(self, env, checkpoint: str | None = None, hold: int = 5, seed: int = 0, **_):
        self.n, self.dim, self.device = env.num_envs, env.platform.action_dim, env.device
        self.hold = hold
        self.generator = torch.Generator().manual_seed(seed)
        self.action = torch.zeros(self.n, self.dim)
        self.age = torch.zeros(self.n, dtype=torch.long)

    def reset(self, env_idx):
        self.age[env_idx.cpu()] = 0

    def act(self, obs):
        fresh = self.age % self.hold == 0
        sample = torch.rand(self.n, self.dim, generator=self.generator) * 2 - 1
        self.action = torch.where(fresh[:, None], sample, self.action)
        self.age += 1
        return self.action.to(self.device)
