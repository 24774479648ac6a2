"""A batch's per-step state, kept where the env makes it: which envs run, their step counts, what each step recorded.

The rollout runner used to copy every info tensor and the state, task state and action of every step to the host
(one transfer, and on a GPU one synchronization, each) and loop over the batch's rows in Python. Here each step is
written into preallocated `(T, N, ...)` tensors on the env's device; `to_host` makes one transfer per key. Camera
images are the exception (`host_frames`): T x N x 3 cameras of 128x128 RGB-D do not fit a GPU's memory for a
1,000-step batch of 1,024 envs, so they go to the host as they are rendered, as before.
"""

from __future__ import annotations

import numpy as np
import torch

from .chained import ChainMonitor, mark_grasp_lost


class BatchStatus:
    """Which envs of a batch still run, how many steps each ran, and which ran out of time: `(N,)` tensors on the
    env's device, advanced after each step without reading anything to the host."""

    def __init__(self, running: torch.Tensor, monitor: ChainMonitor | None = None):
        self.active = running.clone()  # (N,) bool: the env's episode is still running
        self.steps = torch.zeros_like(running, dtype=torch.long)  # control steps each episode ran
        self.truncated = torch.zeros_like(running)  # ended by a budget (the env's, a chain stage's), not terminated
        self.monitor = monitor

    def advance(self, terminated: torch.Tensor, truncated: torch.Tensor, step: dict[str, torch.Tensor]) -> None:
        """Count the step for the envs that ran it and end those whose episode ended; under the chained protocol the
        monitor's stage budgets and grasp-hold check end episodes too, and a lost grasp is written into `step`."""
        live = self.active.clone()
        self.steps += live.long()
        ended = (terminated | truncated) & live
        self.truncated |= truncated & ~terminated & live
        if self.monitor is not None:
            over_budget, grasp_lost = self.monitor.update(step)
            grasp_lost &= live & ~ended
            mark_grasp_lost(step, grasp_lost)
            self.truncated |= over_budget & live & ~ended
            ended |= (over_budget | grasp_lost) & live
        self.active &= ~ended

    def out_of_time(self) -> None:
        """The step budget is spent: the episodes still running were truncated."""
        self.truncated |= self.active


class StepBuffer:
    """`(T, N, ...)` tensors filled one step at a time; the keys and shapes are those of the first step."""

    def __init__(self, max_steps: int):
        self.max_steps = max_steps
        self.steps = 0
        self._data: dict[str, torch.Tensor] = {}

    def append(self, step: dict[str, torch.Tensor]) -> None:
        """Copy one step's `(N, ...)` tensors in (a copy: an env may reuse its info tensors in the next step)."""
        if self.steps >= self.max_steps:
            raise ValueError(f"a batch ran more than its {self.max_steps} steps")
        if not self._data:
            self._data = {k: torch.empty((self.max_steps, *v.shape), dtype=v.dtype, device=v.device)
                          for k, v in step.items()}
        elif step.keys() != self._data.keys():
            raise ValueError(f"step {self.steps} has the keys {sorted(step)}, the first step had {sorted(self._data)}")
        for key, value in step.items():
            self._data[key][self.steps].copy_(value.detach())
        self.steps += 1

    def to_host(self) -> dict[str, np.ndarray]:
        """Every key's `(steps, N, ...)` array on the host: one transfer per key."""
        return {k: v[: self.steps].cpu().numpy() for k, v in self._data.items()}


def per_env_signals(info: dict, num_envs: int) -> dict[str, torch.Tensor]:
    """The info entries that are per-env tensors `(N, ...)`: the signals annotation reads (scalars are left out)."""
    return {k: v for k, v in info.items() if torch.is_tensor(v) and v.shape[:1] == (num_envs,)}
