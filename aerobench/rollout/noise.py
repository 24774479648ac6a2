"""Noise injection while collecting demonstrations (DART: Laskey et al., 2017, "DART: Noise Injection for Robust
Imitation Learning").

A demonstrator that never errs records only the states on its own path; a cloned policy that drifts a few mm off it
meets states the data never showed and has no correction to copy. With `action_noise` sigma the runner executes the
policy's action plus Gaussian noise on the flight dimensions (normalised velocity and yaw-rate commands), while the
dataset records the policy's own action: the demonstrations then visit perturbed states *with* the expert's
correcting labels. The gripper and arm dimensions are never perturbed. Measured use: the Place release, where the
open fingers clear a 102 mm can by 4 mm a side (docs/experiments.md, "What fails: the master chef can's release").
"""

from __future__ import annotations

import math

import torch

from ..envs.platforms import FLIGHT_ACTION_DIMS

MAX_ACTION_NOISE = 0.5  # beyond this the "demonstrations" are mostly noise


def check_action_noise(sigma: float) -> float:
    """`sigma` as a float, or a one-line ValueError."""
    if not (isinstance(sigma, int | float) and math.isfinite(sigma) and 0.0 <= sigma <= MAX_ACTION_NOISE):
        raise ValueError(f"--action-noise must be a standard deviation between 0 and {MAX_ACTION_NOISE} (normalised "
                         f"action units, e.g. 0.05), got {sigma!r}")
    return float(sigma)


class ActionNoise:
    """Adds N(0, sigma^2) to the flight dimensions of a batch of actions `(N, A)`, row i from a generator seeded with
    its episode's seed (`seeds[i]`, and again by `restart` when an env begins its next episode): an episode's noise is
    its seed's, whatever the batch it runs in or the episodes before it on its env. The result stays within the action
    bounds [-1, 1]."""

    def __init__(self, sigma: float, seeds: list[int]):
        self.sigma = check_action_noise(sigma)
        self.generators = [torch.Generator(device="cpu") for _ in seeds]  # CPU draws: the same noise on any device
        self.restart(list(range(len(seeds))), seeds)

    def restart(self, rows: list[int], seeds: list[int]) -> None:
        """Envs `rows` begin the episodes of `seeds`."""
        for row, seed in zip(rows, seeds, strict=True):
            self.generators[row].manual_seed(int(seed))

    def __call__(self, action: torch.Tensor) -> torch.Tensor:
        if self.sigma == 0.0:
            return action
        noise = torch.cat([torch.randn((1, FLIGHT_ACTION_DIMS), generator=g) for g in self.generators]) * self.sigma
        executed = action.clone()
        executed[:, :FLIGHT_ACTION_DIMS] = (executed[:, :FLIGHT_ACTION_DIMS] + noise.to(action.device)).clamp(-1.0, 1.0)
        return executed


__all__ = ["ActionNoise", "FLIGHT_ACTION_DIMS", "check_action_noise"]
