"""The policies that need no training: the privileged expert and a uniform random policy."""

from __future__ import annotations

import numpy as np
import torch

from .. import tiers
from ..expert import ExpertController
from .registry import register_policy


@register_policy("expert")
class ExpertPolicy:
    """The privileged hybrid expert (reads simulator state, not the observation). `look_first`: a Pick expert that
    first turns on the spot to face its object (`expert.look`; demonstrations for camera policies)."""

    name = "expert"
    input_tier = staticmethod(lambda checkpoint=None: tiers.PRIVILEGED.name)  # it acts on the simulator's state

    def __init__(self, env, checkpoint: str | None = None, look_first: bool = False, **_):
        if checkpoint:
            raise ValueError("the expert policy takes no --checkpoint")
        self.controller = ExpertController(env, look_first=look_first)

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
    """Uniform random actions in [-1, 1], each held for `hold` control steps, drawn from a generator seeded by the
    episode's own seed (`seed` offsets every stream): two episodes never replay one action sequence, and an episode
    replays its own exactly."""

    name = "random"
    input_tier = staticmethod(lambda checkpoint=None: tiers.NO_INPUTS)  # it reads nothing
    TABLE_ROWS = 1024  # held actions drawn per episode at its reset: 5120 control steps at hold 5, then they repeat

    def __init__(self, env, checkpoint: str | None = None, hold: int = 5, seed: int = 0, **_):
        self.env, self.n, self.dim, self.device = env, env.num_envs, env.platform.action_dim, env.device
        self.hold, self.seed = hold, seed
        self.table = torch.zeros(self.n, self.TABLE_ROWS, self.dim)
        self.age = torch.zeros(self.n, dtype=torch.long)

    def reset(self, env_idx):
        seeds = np.atleast_1d(np.asarray(self.env._episode_seed)).astype(np.int64)
        for i in env_idx.cpu().tolist():  # once per episode, at its start (not per step)
            generator = torch.Generator().manual_seed(int(seeds[i if len(seeds) > 1 else 0]) + self.seed)
            self.table[i] = torch.rand(self.TABLE_ROWS, self.dim, generator=generator) * 2 - 1
        self.age[env_idx.cpu()] = 0

    def act(self, obs):
        rows = (self.age // self.hold) % self.TABLE_ROWS
        action = self.table[torch.arange(self.n), rows]
        self.age += 1
        return action.to(self.device)
