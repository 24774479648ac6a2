"""PPO's rollout workers on physx_cpu (`aerobench train ppo --num-envs K`): K skill envs in K worker processes
(gymnasium's `AsyncVectorEnv`, spawned) or K Ray actors (`--ray`), the learner in the calling process.

physx_cpu runs one env per process. Each worker holds one env and a copy of the policy and collects a whole window
(`aerobench.train.ppo_rollout.Collector`): actor inference runs beside the physics, and a window costs the learner
one round trip per worker (the policy out, the `(T, 1, ...)` fragment back) instead of one per env step, with each
worker's resets inside its own window rather than holding up the others. Worker `i` of `K` is lane `i` of the
start schedule, so its starts are disjoint from the other workers' and traceable to their seeds.

gymnasium's vector env is used for its process management and calls (`call`: the same method on every worker);
the workers are never stepped as envs, so their observation and action spaces are placeholders, and a worker builds
its env on `start()` (the vector env makes one throwaway instance in the calling process to read those spaces).
"""

from __future__ import annotations

import dataclasses
from functools import partial
from typing import Any

import gymnasium as gym
import numpy as np
import torch

from .ppo_rollout import Collector, Fragment, SkillEnv, state_dim


def plain(value: Any) -> Any:
    """Tensors (also in dicts, lists and `Fragment`s) as numpy arrays. Sent through a pipe once torch is imported,
    a tensor travels as a shared-memory handle that the receiver must fetch (measured: about 20 ms per window for the
    dozen small tensors of a fragment); as an array it is pickled inline (under 2 ms)."""
    return _convert(value, lambda t: t.numpy())


def tensors(value: Any) -> Any:
    """The inverse of `plain`."""
    return _convert(value, torch.from_numpy, np.ndarray)


def _convert(value: Any, fn, kind=torch.Tensor) -> Any:
    if isinstance(value, kind):
        return fn(value)
    if isinstance(value, dict):
        return type(value)((k, _convert(v, fn, kind)) for k, v in value.items())
    if isinstance(value, list):
        return [_convert(v, fn, kind) for v in value]
    if isinstance(value, Fragment):
        return dataclasses.replace(value, **{f.name: _convert(getattr(value, f.name), fn, kind)
                                             for f in dataclasses.fields(value)})
    return value


class RolloutWorker(gym.Env):
    """One worker: its `SkillEnv` (lane `lane` of `lanes`) and, from the first `collect`, a `Collector` with a copy
    of the policy. `config` is the run's `PPOConfig`."""

    observation_space = action_space = gym.spaces.Box(0.0, 1.0, (1,), np.float32)  # placeholders (never stepped)

    def __init__(self, config, obs_mode: str, lane: int, lanes: int, episodes_started: int):
        self.args = (config, obs_mode, lane, lanes, episodes_started)
        self.env: SkillEnv | None = None
        self.collector: Collector | None = None

    def start(self) -> str:
        """Build the env and draw its first start (one torch thread: one core per worker); returns its platform."""
        torch.set_num_threads(1)
        config, obs_mode, lane, lanes, started = self.args
        self.env = SkillEnv(config, obs_mode, 1, lane, lanes, started)
        self.first = self.env.reset_all()
        return self.env.platform.name

    def state_dim(self, inputs: dict) -> int:
        """The actor's state width for input spec `inputs` (an `InputSpec` as a dict) on this env."""
        from ..policies.inputs import InputSpec

        return state_dim(self.env, self.first[0], InputSpec.from_dict(inputs))

    def collect(self, model: dict, policy: dict, steps: int, gamma: float, seed: int) -> Fragment:
        """One window of `steps` with the learner's `policy` (sent `plain`); the action noise is seeded with `seed`
        and the lane. Returns the fragment `plain`."""
        from ..policies.inputs import InputSpec
        from ..policies.learned import Normalizer, make_actor, make_critic

        policy = tensors(policy)
        if self.collector is None:
            log_std = torch.nn.Parameter(policy["log_std"].clone(), requires_grad=False)
            self.collector = Collector(self.env, *self.first, InputSpec.from_dict(model["inputs"]), model,
                                       make_actor(model), make_critic(model), log_std,
                                       Normalizer({k: v.tolist() for k, v in policy["normalizer"].items()}))
        self.collector.load_policy(policy)
        torch.manual_seed(seed * self.env.lanes + self.env.lane)
        return plain(self.collector.collect(steps, gamma))

    def close(self) -> None:
        if self.env is not None:
            self.env.close()


class ProcessWorkers:
    """K `RolloutWorker`s in K spawned processes (gymnasium's `AsyncVectorEnv`)."""

    def __init__(self, config, obs_mode: str, num_workers: int, episodes_started: int):
        from gymnasium.vector import AsyncVectorEnv

        self.vec = AsyncVectorEnv(
            [partial(RolloutWorker, config, obs_mode, i, num_workers, episodes_started) for i in range(num_workers)],
            context="spawn", shared_memory=False)
        self.platform_name = self.vec.call("start")[0]

    def call(self, name: str, *args) -> list:
        return tensors(list(self.vec.call(name, *plain(list(args)))))

    def close(self) -> None:
        self.vec.close()


class RayWorkers:
    """K `RolloutWorker`s as Ray actors (one CPU each) of a local runtime (`address` "local") or a cluster. An actor
    that dies ends the run with Ray's error (a resume continues from the last checkpoint)."""

    def __init__(self, config, obs_mode: str, num_workers: int, episodes_started: int, address: str):
        import ray

        from ..rollout.ray_shards import connect

        connect(address)
        actor = ray.remote(num_cpus=1)(RolloutWorker)
        self._ray = ray
        self.actors = [actor.remote(config, obs_mode, i, num_workers, episodes_started) for i in range(num_workers)]
        self.platform_name = self.call("start")[0]

    def call(self, name: str, *args) -> list:
        return tensors(self._ray.get([getattr(a, name).remote(*plain(list(args))) for a in self.actors]))

    def close(self) -> None:
        for actor in self.actors:
            self._ray.kill(actor)
