"""One random generator per parallel env, seeded by that env's episode seed: every random draw of a reset comes from it.

ManiSkill 3.0.1 seeds torch's global generator with env 0's episode seed (`torch.manual_seed(_episode_seed[0])`)
around `_initialize_episode`, so in a batch every env's start came from one stream and depended on its row and on the
other envs' draws. Here env `i` owns a torch CPU generator, seeded with `_episode_seed[i]` whenever ManiSkill sets
a new episode seed for it (a seeded reset, or a reconfiguring one; `AerialEnv._set_episode_rng`), and each draw of a
reset calls it once per env being reset with the shape a one-env reset draws. So:
- a batch reset with seeds `[s1..sN]` draws exactly what N one-env resets with those seeds draw, whatever the row,
  the batch size or the other envs (a sampler that draws must not decide *whether* to draw for one env from another
  env's values: see `PickEvaluator.sample`);
- one env draws exactly what torch's global generator drew after `torch.manual_seed(s)` (that and
  `torch.Generator().manual_seed(s)` start the same stream), so today's one-env starts are unchanged
  (tests/envs/test_episode_starts.py);
- a reset with no seed continues each env's stream (ManiSkill keeps the old episode seed then: reseeding would repeat
  the last start).

Draws are made on the CPU and moved to the env's device: a seed names the same draws on `physx_cpu` and `physx_cuda`
(CUDA's generator is another stream). A reset pays a few small CPU calls per env per draw; the step never draws.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch


def _rows(env_idx: torch.Tensor | Sequence[int]) -> list[int]:
    return env_idx.tolist() if isinstance(env_idx, torch.Tensor) else [int(i) for i in env_idx]


class EpisodeRNG:
    """`num_envs` torch CPU generators; draws `(M, *shape)` for the envs `env_idx` `(M,)`, on `device`."""

    def __init__(self, num_envs: int, device: torch.device | str):
        self.device = torch.device(device)
        self.generators = [torch.Generator() for _ in range(num_envs)]

    def __len__(self) -> int:
        return len(self.generators)

    def __getitem__(self, env: int) -> torch.Generator:
        return self.generators[env]

    def seed(self, env_idx: torch.Tensor | Sequence[int], seeds: Sequence[int]) -> None:
        """Restart env `env_idx[k]`'s stream at `seeds[k]`."""
        rows = _rows(env_idx)
        if len(rows) != len(seeds):
            raise ValueError(f"{len(seeds)} seeds for {len(rows)} envs")
        for i, s in zip(rows, seeds):
            self.generators[i].manual_seed(int(s))

    def _per_env(self, env_idx, shape: tuple[int, ...], dtype: torch.dtype,
                 draw: Callable[[torch.Generator], torch.Tensor]) -> torch.Tensor:
        rows = _rows(env_idx)
        if not rows:
            return torch.empty((0, *shape), dtype=dtype, device=self.device)
        return torch.cat([draw(self.generators[i]) for i in rows]).to(self.device)

    def rand(self, env_idx, *shape: int) -> torch.Tensor:
        """Uniform [0, 1) `(M, *shape)`: env `i`'s row is `torch.rand(1, *shape)` from its stream."""
        return self._per_env(env_idx, shape, torch.float32, lambda g: torch.rand((1, *shape), generator=g))

    def randn(self, env_idx, *shape: int) -> torch.Tensor:
        """Standard normal `(M, *shape)`: env `i`'s row is `torch.randn(1, *shape)` from its stream."""
        return self._per_env(env_idx, shape, torch.float32, lambda g: torch.randn((1, *shape), generator=g))

    def randint(self, high: int, env_idx, *shape: int) -> torch.Tensor:
        """Integers in [0, high) `(M, *shape)`: env `i`'s row is `torch.randint(high, (1, *shape))` from its stream."""
        return self._per_env(env_idx, shape, torch.int64, lambda g: torch.randint(high, (1, *shape), generator=g))

    def multinomial(self, env_idx, weights: Sequence[torch.Tensor]) -> torch.Tensor:
        """One index `(M,)` per env, drawn from its `weights[k]` `(K_k,)` (each env's own row, unpadded: the number of
        weights changes how much of the stream a draw uses)."""
        rows = _rows(env_idx)
        if len(weights) != len(rows):
            raise ValueError(f"{len(weights)} weight rows for {len(rows)} envs")
        if not rows:
            return torch.empty(0, dtype=torch.int64, device=self.device)
        picks = [torch.multinomial(w.detach().cpu()[None], 1, generator=self.generators[i])[:, 0]
                 for i, w in zip(rows, weights)]
        return torch.cat(picks).to(self.device)
