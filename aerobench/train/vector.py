"""K physx_cpu skill envs in K worker processes, seen as one batched env (what `aerobench train ppo --num-envs K`
steps on a CPU machine; with `--ray`, the K workers are Ray actors, on this machine or a cluster).

physx_cpu runs one env per process, so the batch is gymnasium's `AsyncVectorEnv` (spawned workers, autoreset
disabled: the trainer decides when and which envs reset, as it does with a batched physx_cuda env). Each worker holds
one ManiSkill skill env behind `OneEnv`, which turns its `(1, ...)` torch outputs into the plain arrays gymnasium
batches and carries the task state in the observation. `ProcessBatchedEnv` turns the batch back into the torch
tensors and dict shapes of a batched ManiSkill env, so the trainer has one code path for both.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import torch


class OneEnv(gym.Wrapper):
    """One skill env (`num_envs=1`) as a plain gymnasium env: numpy observation `{"state", "task_state"}`, scalar
    reward and flags, an info of scalars. `reset(options={"objects": [...]})` takes the object of its own index."""

    def __init__(self, env: gym.Env, index: int):
        super().__init__(env)
        self.index = index
        base = env.unwrapped
        self.platform_name = base.platform.name
        obs = {k: v.shape[-1] for k, v in self._numpy_obs(base.get_obs()).items()}
        self.observation_space = gym.spaces.Dict(
            {k: gym.spaces.Box(-np.inf, np.inf, (n,), np.float32) for k, n in obs.items()})
        self.action_space = gym.spaces.Box(-1.0, 1.0, (base.platform.action_dim,), np.float32)

    def _numpy_obs(self, obs) -> dict[str, np.ndarray]:
        task_state = self.env.unwrapped.task_state()
        return {"state": obs["agent"]["state"][0].cpu().numpy().astype(np.float32),
                "task_state": task_state[0].cpu().numpy().astype(np.float32)}

    @staticmethod
    def _scalar_info(info: dict) -> dict[str, Any]:
        return {k: v[0].item() for k, v in info.items() if torch.is_tensor(v) and v.ndim >= 1 and v.shape[0] == 1
                and v[0].numel() == 1}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        options = dict(options or {})
        objects = options.pop("objects", None)
        options["reconfigure"] = True  # a new layout per episode, as the batched trainer's resets draw
        if objects:
            options["objects"] = [objects[self.index]]
        obs, info = self.env.reset(seed=seed, options=options)
        return self._numpy_obs(obs), self._scalar_info(info)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(torch.as_tensor(action, dtype=torch.float32)[None])
        return (self._numpy_obs(obs), float(reward[0]), bool(terminated[0]), bool(truncated[0]),
                self._scalar_info(info))


def _make_one(env_id: str, kwargs: dict, index: int):
    def make() -> gym.Env:
        torch.set_num_threads(1)  # one core per worker process
        import aerobench.envs  # noqa: F401 - registers the envs in the spawned process

        return OneEnv(gym.make(env_id, num_envs=1, **kwargs), index)

    return make


class WorkerBatchedEnv:
    """`num_envs` one-env workers behind the interface of a batched ManiSkill env: `reset(seed=[...],
    options={"objects": [...], "env_idx": idx})`, `step(actions)` with `(N, ...)` tensors and an info of `(N,)`
    tensors, `task_state()`, `platform`, `num_envs`, `device`. Subclasses say how the workers run."""

    num_envs: int
    platform: Any
    device = torch.device("cpu")
    _obs: dict[str, torch.Tensor] | None = None

    def _batch(self, obs: dict[str, np.ndarray], info: dict) -> tuple[dict, dict]:
        fresh = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in obs.items()}
        if self._obs is None:
            self._obs = fresh
        mask = info.get("_reset_mask")
        for k, v in fresh.items():  # a partial reset returns every row; only the reset rows are new
            self._obs[k] = v if mask is None else torch.where(torch.as_tensor(mask)[:, None], v, self._obs[k])
        tensors = {k: torch.as_tensor(np.asarray(v)) for k, v in info.items() if not k.startswith("_")}
        return {"agent": {"state": self._obs["state"].clone()}}, tensors

    def task_state(self) -> torch.Tensor:
        return self._obs["task_state"].clone()


class ProcessBatchedEnv(WorkerBatchedEnv):
    """The workers as local spawned processes (gymnasium's `AsyncVectorEnv`)."""

    def __init__(self, env_id: str, num_envs: int, **kwargs):
        from gymnasium.vector import AsyncVectorEnv, AutoresetMode

        from ..envs.platforms import get_platform

        self.num_envs = num_envs
        self.vec = AsyncVectorEnv([_make_one(env_id, kwargs, i) for i in range(num_envs)], context="spawn",
                                  autoreset_mode=AutoresetMode.DISABLED, shared_memory=False)
        self.platform = get_platform(self.vec.get_attr("platform_name")[0])

    def reset(self, seed: Sequence[int] | int | None = None, options: dict | None = None):
        options = dict(options or {})
        idx = options.pop("env_idx", None)
        if isinstance(seed, int):
            seed = [seed + i for i in range(self.num_envs)]
        mask = None
        if idx is not None:
            mask = np.zeros(self.num_envs, dtype=bool)
            mask[torch.as_tensor(idx).cpu().numpy()] = True
            options["reset_mask"] = mask  # gymnasium takes it out of the options
        obs, info = self.vec.reset(seed=list(seed) if seed is not None else None, options=options)
        if mask is not None:
            info["_reset_mask"] = mask
        return self._batch(obs, info)

    def step(self, action: torch.Tensor):
        obs, reward, terminated, truncated, info = self.vec.step(action.detach().cpu().numpy())
        obs_t, info_t = self._batch(obs, info)
        return (obs_t, torch.as_tensor(reward, dtype=torch.float32), torch.as_tensor(terminated),
                torch.as_tensor(truncated), info_t)

    def close(self) -> None:
        self.vec.close()


class _EnvActor:
    """A Ray actor holding one `OneEnv` (made a Ray actor class in `RayBatchedEnv`: Ray is imported only there)."""

    def __init__(self, env_id: str, kwargs: dict, index: int):
        self.env = _make_one(env_id, kwargs, index)()

    def platform_name(self) -> str:
        return self.env.platform_name

    def reset(self, seed: int | None, options: dict):
        return self.env.reset(seed=seed, options=options)

    def step(self, action: np.ndarray):
        return self.env.step(action)

    def close(self) -> None:
        self.env.close()


class RayBatchedEnv(WorkerBatchedEnv):
    """The workers as Ray actors (one CPU each) of a local runtime (`address` "local") or a cluster: PPO's rollout
    workers, with the learner in the driver. An actor that dies ends the run with Ray's error (a resume continues
    from the last checkpoint)."""

    def __init__(self, env_id: str, num_envs: int, address: str, **kwargs):
        import ray

        from ..envs.platforms import get_platform
        from ..rollout.ray_shards import connect

        connect(address)
        actor = ray.remote(num_cpus=1)(_EnvActor)
        self.num_envs, self._ray = num_envs, ray
        self.actors = [actor.remote(env_id, kwargs, i) for i in range(num_envs)]
        self.platform = get_platform(ray.get(self.actors[0].platform_name.remote()))

    def _gather(self, results: list[tuple], rows: list[int]) -> tuple[dict, dict]:
        """Per-env (obs, ..., info) of `rows` -> gymnasium's batched layout (rows not in `rows` are zeros)."""
        obs = {k: np.zeros((self.num_envs, *np.shape(v)), np.float32) for k, v in results[0][0].items()}
        keys = {k for r in results for k in r[-1]}
        info = {k: np.zeros(self.num_envs, dtype=np.asarray(results[0][-1].get(k, 0.0)).dtype) for k in keys}
        for row, result in zip(rows, results):
            for k, v in result[0].items():
                obs[k][row] = v
            for k, v in result[-1].items():
                info[k][row] = v
        return obs, info

    def reset(self, seed: Sequence[int] | int | None = None, options: dict | None = None):
        options = dict(options or {})
        idx = options.pop("env_idx", None)
        rows = list(range(self.num_envs)) if idx is None else [int(i) for i in torch.as_tensor(idx).tolist()]
        seeds = [seed + i for i in range(self.num_envs)] if isinstance(seed, int) else list(seed or [None] * self.num_envs)
        results = self._ray.get([self.actors[i].reset.remote(seeds[i], options) for i in rows])
        obs, info = self._gather(results, rows)
        if idx is not None:
            mask = np.zeros(self.num_envs, dtype=bool)
            mask[rows] = True
            info["_reset_mask"] = mask
        return self._batch(obs, info)

    def step(self, action: torch.Tensor):
        actions = action.detach().cpu().numpy()
        results = self._ray.get([a.step.remote(actions[i]) for i, a in enumerate(self.actors)])
        obs, info = self._gather(results, list(range(self.num_envs)))
        obs_t, info_t = self._batch(obs, info)
        reward, terminated, truncated = (torch.as_tensor(np.array([r[i] for r in results])) for i in (1, 2, 3))
        return obs_t, reward.float(), terminated, truncated, info_t

    def close(self) -> None:
        for actor in self.actors:
            self._ray.kill(actor)
