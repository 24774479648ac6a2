"""A batch's per-step state, kept where the env makes it: which envs run, their step counts, what each step recorded.

The rollout runner used to copy every info tensor and the state, task state and action of every step to the host
(one transfer, and on a GPU one synchronization, each) and loop over the batch's rows in Python. Here each step is
written into a preallocated ring of `(T, N, ...)` tensors on the env's device, T the longest an episode runs; when
episodes end, `rows_to_host` makes one transfer per key for all of them, and `episode_steps` cuts each one's steps out
on the host. A ring, because with partial resets (`RolloutSpec.episodes_per_scene`) an env's next episode starts
while the others run on: `Wave` keeps the step each env's episode began at, and its steps are cut from there. Camera images are the
exception (`host_frames`): T x N x 3 cameras of 128x128 RGB-D do not fit a GPU's memory for a 1,000-step batch of
1,024 envs, so they go to the host as they are rendered, as before.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator

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
        self.ended = torch.zeros_like(running)  # the episodes that ended at the last step (`advance`)
        self.monitor = monitor

    def restart(self, rows: torch.Tensor, running: torch.Tensor) -> None:
        """Envs `rows` `(M,)` begin a new episode (a partial reset); `running` `(M,)` False for a start that failed."""
        self.active[rows] = running
        self.steps[rows] = 0
        self.truncated[rows] = False
        self.ended[rows] = False

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
        self.ended = ended

    def out_of_time(self) -> None:
        """The step budget is spent: the episodes still running were truncated."""
        self.truncated |= self.active


class StepBuffer:
    """A ring of the last `capacity` steps' `(N, ...)` tensors (the keys and shapes are those of the first step)."""

    def __init__(self, capacity: int):
        self.capacity = capacity
        self.steps = 0  # steps appended in all; step t sits at position t % capacity
        self._data: dict[str, torch.Tensor] = {}

    def append(self, step: dict[str, torch.Tensor]) -> None:
        """Copy one step's `(N, ...)` tensors in (a copy: an env may reuse its info tensors in the next step)."""
        if not self._data:
            self._data = {k: torch.empty((self.capacity, *v.shape), dtype=v.dtype, device=v.device)
                          for k, v in step.items()}
        elif step.keys() != self._data.keys():
            raise ValueError(f"step {self.steps} has the keys {sorted(step)}, the first step had {sorted(self._data)}")
        position = self.steps % self.capacity
        for key, value in step.items():
            self._data[key][position].copy_(value.detach())
        self.steps += 1

    def rows_to_host(self, rows: list[int]) -> dict[str, np.ndarray]:
        """The whole ring of envs `rows`, `(capacity, len(rows), ...)` per key: one transfer per key."""
        index = torch.tensor(rows, dtype=torch.long)
        return {k: v[:, index.to(v.device)].cpu().numpy() for k, v in self._data.items()}

    def episode_steps(self, host: dict[str, np.ndarray], column: int, first: int, steps: int) -> dict[str, np.ndarray]:
        """Of `rows_to_host`'s arrays, column `column`'s steps `first` .. `first + steps - 1` (counted from the first
        step appended), `(steps, ...)` per key."""
        if first + steps > self.steps or self.steps - first > self.capacity:
            raise ValueError(f"steps {first}..{first + steps - 1} are not in the ring ({self.capacity} of the "
                             f"{self.steps} steps written)")
        positions = np.arange(first, first + steps) % self.capacity
        return {k: v[positions, column].copy() for k, v in host.items()}


class Wave:
    """One reconfigured batch while it runs: its status, what its steps recorded (the state, task state, action and
    phase in `frames`, the info signals in `signals`, the rendered images on the host in `images`), and each env's
    current episode: the step it began at, whether its start failed, its instruction."""

    def __init__(self, base, status: BatchStatus, capacity: int):
        self.base, self.status = base, status
        self.signals, self.frames = StepBuffer(capacity), StepBuffer(capacity)  # `capacity`: the longest episode
        self.images: deque[dict[str, np.ndarray]] = deque(maxlen=capacity)
        n = base.num_envs
        self.first = [0] * n
        self.init_failed = torch.zeros(n, dtype=torch.bool, device=status.active.device)
        self.tasks = [""] * n

    def begin(self, rows: list[int], failed: torch.Tensor) -> list[int]:
        """Envs `rows` begin episodes at the next step, those with `failed` `(M,)` not at all; returns the latter."""
        index = torch.tensor(rows, dtype=torch.long, device=self.init_failed.device)
        self.init_failed[index] = failed
        self.status.restart(index, ~failed)
        for i in rows:
            self.first[i] = self.frames.steps
            self.tasks[i] = self.base.get_instruction(i)
        return [i for i, f in zip(rows, failed.tolist()) if f]

    def episodes(self, rows: list[int]) -> Iterator[tuple[dict, list[dict], dict, int, bool, bool, str]]:
        """Each of `rows`' episodes (ended): its frames `(T, ...)`, its images (one dict a step), its signals,
        its step count, whether it was truncated, whether its start failed, its instruction."""
        frame_ring, trace_ring = self.frames.rows_to_host(rows), self.signals.rows_to_host(rows)
        steps, truncated = self.status.steps[rows].tolist(), self.status.truncated[rows].tolist()
        failed = self.init_failed[rows].tolist()
        offset = self.frames.steps - len(self.images)  # the step the oldest image kept was rendered at
        for k, i in enumerate(rows):
            first, count = self.first[i], steps[k]
            shots = [{key: value[i] for key, value in self.images[t - offset].items()} for t in range(first, first + count)]
            yield (self.frames.episode_steps(frame_ring, k, first, count), shots,
                   self.signals.episode_steps(trace_ring, k, first, count), count, truncated[k], failed[k], self.tasks[i])


def per_env_signals(info: dict, num_envs: int) -> dict[str, torch.Tensor]:
    """The info entries that are per-env tensors `(N, ...)`: the signals annotation reads (scalars are left out)."""
    return {k: v for k, v in info.items() if torch.is_tensor(v) and v.shape[:1] == (num_envs,)}
