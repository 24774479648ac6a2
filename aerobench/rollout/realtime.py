"""Real-time evaluation: the simulation keeps stepping while the policy computes (`aerobench eval --realtime`).

Timing model, in control steps of dt = 1 / control rate (50 ms at aerobench's 20 Hz):

- A latency of L ms is k = ceil(L / dt) control steps (L = 0: k = 0, today's evaluation, step for step).
- The policy answers one request at a time. A request sent at step t carries the observation of step t; its answer
  (one action, or a chunk of n actions for ACT, pi0, pi0.5, or any policy served by LeRobot's PolicyServer) applies
  at steps t + k, t + k + 1, ..., t + k + n - 1. A chunk plays from its first action, as LeRobot's `select_action`
  queue plays it on a robot.
- When a request is sent (`schedule`):
  - `sync` (LeRobot's synchronous loop): when the robot has no action left: the drone holds for k steps per request;
  - `async` (LeRobot's async inference): as soon as the policy is free and the actions queued cover at most the
    next k steps, so a chunk longer than k arrives as the last one runs out (no hold after the first request),
    acted on an observation k steps old.
- A step with no action from the policy runs the hold command (`hold`): `last` repeats the command of the step
  before; `hover` commands zero velocity and yaw rate and keeps the gripper (and arm) command of the step before.
  Before the episode's first answer, the command of the step before is the one the controllers hold after the
  reset: hover, the arm at its working pose, the gripper open (closed where the episode starts holding its object).
- With `latency_ms=None` the latency is the policy's own: the wall time of each request's call (for a policy behind
  LeRobot's PolicyServer, the round trip), so k >= 1 and it varies from request to request.

The schedule is batch-wide: the runner resets a batch's envs together and the policy acts on the batch at once.
Each step's timing (command age, hold, the latency of a request sent then) is kept for the episode's record.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from ..envs.platforms import FLIGHT_ACTION_DIMS

HOLDS = ("last", "hover")
SCHEDULES = ("sync", "async")


@dataclass(frozen=True)
class RealtimeSpec:
    """The real-time settings: a fixed latency in ms (None: the policy's own, measured per request), the hold
    command, and when requests are sent."""

    latency_ms: float | None = None
    hold: str = "last"
    schedule: str = "sync"

    def __post_init__(self):
        if self.latency_ms is not None and not (math.isfinite(self.latency_ms) and self.latency_ms >= 0):
            raise ValueError(f"--inference-latency-ms must be a finite number >= 0, got {self.latency_ms}")
        if self.hold not in HOLDS:
            raise ValueError(f"--hold takes {' or '.join(HOLDS)}, got {self.hold!r}")
        if self.schedule not in SCHEDULES:
            raise ValueError(f"--schedule takes {' or '.join(SCHEDULES)}, got {self.schedule!r}")

    def as_dict(self) -> dict:
        return {"latency_ms": "measured" if self.latency_ms is None else float(self.latency_ms), "hold": self.hold,
                "schedule": self.schedule}


def latency_steps(latency_ms: float, control_dt_s: float) -> int:
    """Control steps that pass before an answer `latency_ms` late applies: ceil(L / dt); a hair of float error above
    a whole number of steps (50 ms / 0.05 s) does not add a step."""
    return max(0, math.ceil(round(latency_ms / (1000.0 * control_dt_s), 9)))


def start_command(base) -> torch.Tensor:
    """`(N, A)` the command the controllers hold right after a reset: hover (zero velocity and yaw rate), the arm at
    its working pose, the gripper open, or closed where the episode starts holding its object (Place)."""
    n, platform = base.num_envs, base.platform
    command = torch.zeros(n, platform.action_dim, device=base.device)
    if platform.arm is not None:
        working = torch.tensor(platform.arm.working_pose_rad, dtype=torch.float32, device=base.device)
        command[:, FLIGHT_ACTION_DIMS:-1] = base.agent.body_controller.arm_action(working.expand(n, -1))
    held = getattr(base, "starts_held", None)
    command[:, -1] = 1.0 if held is None else torch.where(held.to(base.device), -1.0, 1.0)
    return command


@dataclass
class StepTiming:
    """What the env received at one control step."""

    held: bool  # the hold command ran (no action from the policy for this step)
    age_steps: int  # steps since the observation the executed command was computed from; -1: no observation
    request_ms: float | None = None  # the latency of a request sent at this step
    request_steps: int | None = None  # ... in control steps


@dataclass
class _Pending:
    due: int  # the step its first action applies at
    chunk: torch.Tensor  # (N, n, A)
    observed: int  # the step whose observation it answers


class RealtimePolicy:
    """Wraps a policy (`act(obs) -> (N, A)`; chunked ones also `act_chunk(obs) -> (N, n, A)` and `chunked = True`)
    under the timing model above. Other attributes (the expert's `phase`, `infeasible`) are the wrapped policy's."""

    def __init__(self, policy, base, spec: RealtimeSpec, clock: Callable[[], float] = time.perf_counter):
        unsupported = getattr(policy, "realtime_unsupported", None)
        if unsupported:
            raise ValueError(unsupported)
        self.policy, self.base, self.spec, self.clock = policy, base, spec, clock
        self.control_dt_s = 1.0 / float(base.control_freq)
        self.timings: list[StepTiming] = []
        self._reset_schedule()

    def __getattr__(self, name):  # only reached for names the wrapper lacks
        if "policy" not in self.__dict__:
            raise AttributeError(name)
        return getattr(self.__dict__["policy"], name)

    def _reset_schedule(self) -> None:
        self.step = 0
        self.queue: list[tuple[torch.Tensor, int]] = []  # (action (N, A), the step it was observed at)
        self.pending: _Pending | None = None
        self.last = start_command(self.base)
        self.last_observed = -1  # the step whose observation `last` was computed from; -1: none
        self.last_k = 0  # the latency of the last request, in steps (async asks ahead by this much)
        self.timings = []

    def reset(self, env_idx: torch.Tensor) -> None:
        self.policy.reset(env_idx)
        self._reset_schedule()

    def _request(self, obs) -> tuple[torch.Tensor, float]:
        start = self.clock()
        if getattr(self.policy, "chunked", False):
            chunk = self.policy.act_chunk(obs)
        else:
            chunk = self.policy.act(obs)[:, None]
        if chunk.is_cuda:
            torch.cuda.synchronize(chunk.device)  # the measured time includes the kernels, not only their launch
        measured_ms = 1000.0 * (self.clock() - start)
        return chunk, measured_ms if self.spec.latency_ms is None else float(self.spec.latency_ms)

    def act(self, obs) -> torch.Tensor:
        t = self.step
        if self.pending is not None and self.pending.due <= t:
            p, self.pending = self.pending, None
            self.queue.extend((p.chunk[:, i], p.observed) for i in range(p.chunk.shape[1]))
        ahead = self.last_k if self.spec.schedule == "async" else 0
        timing = StepTiming(held=False, age_steps=-1)
        if self.pending is None and len(self.queue) <= ahead:
            chunk, ms = self._request(obs)
            k = latency_steps(ms, self.control_dt_s)
            self.last_k, timing.request_ms, timing.request_steps = k, ms, k
            if k == 0:
                self.queue.extend((chunk[:, i], t) for i in range(chunk.shape[1]))
            else:
                self.pending = _Pending(due=t + k, chunk=chunk, observed=t)
        if self.queue:
            command, observed = self.queue.pop(0)
            timing.age_steps = t - observed
            self.last_observed = observed
        else:
            timing.held = True
            command = self.last.clone()
            if self.spec.hold == "hover":
                command[:, :FLIGHT_ACTION_DIMS] = 0.0
                self.last_observed = -1
            timing.age_steps = t - self.last_observed if self.last_observed >= 0 else -1
        self.last = command
        self.timings.append(timing)
        self.step += 1
        return command

    # ------------------------------------------------------------------------------------------------------------------
    def trace(self, steps: int) -> dict[str, np.ndarray]:
        """Per-step arrays of an episode's first `steps` steps (`EpisodeData.signals`)."""
        rows = self.timings[:steps]
        return {
            "realtime_held": np.array([r.held for r in rows], dtype=bool),
            "realtime_command_age_steps": np.array([r.age_steps for r in rows], dtype=np.int64),
            "realtime_request_ms": np.array([np.nan if r.request_ms is None else r.request_ms for r in rows]),
        }

    def summary(self, steps: int) -> dict:
        """An episode's timing for its record: the settings, its requests' latencies (mean / max, ms and steps), how
        many steps ran the hold command and how old the executed commands' observations were."""
        rows = self.timings[:steps]
        ms = [r.request_ms for r in rows if r.request_ms is not None]
        ks = [r.request_steps for r in rows if r.request_steps is not None]
        ages = [r.age_steps for r in rows if r.age_steps >= 0]

        def mean(values):
            return round(float(np.mean(values)), 3) if values else None

        return {
            **self.spec.as_dict(), "control_dt_s": self.control_dt_s, "requests": len(ms),
            "latency_ms_mean": mean(ms), "latency_ms_max": round(max(ms), 3) if ms else None,
            "latency_steps_mean": mean(ks), "latency_steps_max": max(ks) if ks else None,
            "held_steps": sum(r.held for r in rows),
            "command_age_steps_mean": mean(ages), "command_age_steps_max": max(ages) if ages else None,
        }
