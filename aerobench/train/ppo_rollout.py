"""PPO's rollout: the skill env with its episode bookkeeping, and the collection of one window with the current policy.

`Collector.collect(T)` steps the `N` envs of one `SkillEnv` for `T` steps with the actor (sampled actions), the
critic (values, and the bootstrap of a time-limit cut) and the rewards of `aerobench.train.rewards`, resets finished
episodes, and returns a `Fragment`: the window's `(T, N, ...)` tensors, the critic's value of the last observation
and the episodes that finished in it. The learner (`aerobench.train.ppo`) runs one collector in its own process
(physx_cuda's batch, or one physx_cpu env) or one per rollout worker (`aerobench.train.rollout_workers`: K physx_cpu
envs in K processes, each acting with a copy of the policy, so a window costs one round trip, not one per step).

Episode starts are traceable: the env of lane `i` of `K` (a worker; the learner's own env is lane 0 of 1) starts its
local episode `e` with seed `seed * RESET_SEED_STRIDE + i + K * e`, so the lanes draw disjoint starts and every
start of a run lies below `K * max(episodes started per lane)` (`SkillEnv.starts_bound`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from torch.distributions import Bernoulli, Normal

from ..policies.inputs import InputSpec
from ..policies.learned import Normalizer, env_action
from ..policies.observer import ActorObserver

RESET_SEED_STRIDE = 1_000_003  # episode seed = seed * stride + lane + lanes * (episodes the lane started)
MAX_RESET_TRIES = 20  # a start the env cannot place (init_failed) is re-drawn this often before giving up


class ActionDistribution:
    """The policy's action distribution on the actor's output `(N, A)`: a Gaussian (std `exp(log_std)`) over the
    normalized continuous dimensions and, with a binary gripper, a Bernoulli over "close" (the last output is its
    logit). Samples are `(N, A)`: the continuous values, then the close bit."""

    def __init__(self, out: torch.Tensor, log_std: torch.Tensor, binary: bool):
        self.binary = binary
        self.normal = Normal(out[:, :-1] if binary else out, log_std.exp())
        self.close = Bernoulli(logits=out[:, -1]) if binary else None

    def sample(self) -> torch.Tensor:
        parts = [self.normal.sample()]
        if self.binary:
            parts.append(self.close.sample()[:, None])
        return torch.cat(parts, dim=-1)

    def log_prob(self, action: torch.Tensor) -> torch.Tensor:
        if not self.binary:
            return self.normal.log_prob(action).sum(-1)
        return self.normal.log_prob(action[:, :-1]).sum(-1) + self.close.log_prob(action[:, -1])

    def entropy(self) -> torch.Tensor:
        entropy = self.normal.entropy().sum(-1)
        return entropy + self.close.entropy() if self.binary else entropy


class SkillEnv:
    """The skill env with episode bookkeeping: seeded resets (re-drawn while a start is infeasible), objects
    round-robin over the starts, and per-env partial resets of finished episodes. `num_envs` rows in this process;
    `lane`/`lanes` place its starts among those of other processes (see the module docstring)."""

    def __init__(self, config, obs_mode: str, num_envs: int, lane: int = 0, lanes: int = 1, episodes_started: int = 0):
        import gymnasium as gym

        import aerobench.envs  # noqa: F401 - registers the envs (also in a freshly spawned worker process)

        from ..envs.base_env import freeze_process_heap
        from ..envs.checker import SKILL_ENV_IDS

        self.config, self.n, self.lane, self.lanes = config, num_envs, lane, lanes
        kwargs = dict(setting=config.setting, obs_mode=obs_mode, num_envs=num_envs, sim_backend=config.sim_backend,
                      controller=config.controller)
        if config.platform:
            kwargs["platform"] = config.platform
        if config.max_episode_steps:
            kwargs["max_episode_steps"] = config.max_episode_steps
        if config.objects and len(config.objects) == 1:
            kwargs["object"] = config.objects[0]
        freeze_process_heap()  # a training process resets its envs thousands of times (envs.base_env)
        self.env = gym.make(SKILL_ENV_IDS[config.skill], **kwargs)
        base = self.env.unwrapped
        self.platform, self.task_state, self.device = base.platform, base.task_state, base.device
        self.started = -(-episodes_started // lanes)  # a resumed run's lanes go on above every start it drew

    @property
    def starts_bound(self) -> int:
        """Every episode start this env drew has a start index (seed - seed * stride) below this."""
        return self.lanes * self.started

    def _seeds(self, count: int) -> list[int]:
        base = self.config.seed * RESET_SEED_STRIDE + self.lane
        return [base + self.lanes * (self.started + j) for j in range(count)]

    def _objects(self, count: int) -> list[str] | None:
        objects = self.config.objects
        if not objects or len(objects) == 1:
            return None
        return [objects[(self.lane + self.lanes * (self.started + j)) % len(objects)] for j in range(count)]

    def reset_all(self):
        for _ in range(MAX_RESET_TRIES):
            options = {"reconfigure": True}
            if objects := self._objects(self.n):
                options["objects"] = objects
            seeds = self._seeds(self.n)
            obs, info = self.env.reset(seed=seeds if self.n > 1 else seeds[0], options=options)
            self.started += self.n
            if self.n > 1 or not bool(info["init_failed"].any()):
                break
        else:
            raise RuntimeError(f"{MAX_RESET_TRIES} resets of {self.config.skill} in {self.config.setting} found no "
                               f"feasible start")
        if self.n > 1 and bool(info["init_failed"].any()):
            obs, info = self.reset_some(info["init_failed"].nonzero()[:, 0])
        return obs, info

    def reset_some(self, idx: torch.Tensor):
        """Reset the envs `idx` (all of them on one env); returns the batch's observation and info."""
        if self.n == 1:
            return self.reset_all()
        idx = idx.cpu()
        for _ in range(MAX_RESET_TRIES):  # a batched scene draws its rows' starts from its own generator
            obs, info = self.env.reset(options={"env_idx": idx.to(self.device)})
            self.started += len(idx)
            idx = idx[info["init_failed"][idx].cpu()]
            if len(idx) == 0:
                return obs, info
        raise RuntimeError(f"{MAX_RESET_TRIES} resets found no feasible start for envs {idx.tolist()}")

    def close(self) -> None:
        self.env.close()


@dataclass
class Fragment:
    """One window of one collector: `(T, N, ...)` tensors, the last observation's value and done flags `(N,)`, and
    the episodes that finished (`step`: the window step they ended at, `row`: their env)."""

    inputs: dict[str, torch.Tensor]
    raw_state: torch.Tensor
    actions: torch.Tensor
    logprobs: torch.Tensor
    rewards: torch.Tensor
    dones: torch.Tensor
    values: torch.Tensor
    next_value: torch.Tensor
    next_done: torch.Tensor
    episodes: list[dict] = field(default_factory=list)
    starts_bound: int = 0  # the collector's `SkillEnv.starts_bound` after the window

    @staticmethod
    def join(fragments: list[Fragment]) -> Fragment:
        """The fragments of several collectors side by side (their envs in order); episodes ordered by step."""
        if len(fragments) == 1:
            return fragments[0]
        cat = lambda name: torch.cat([getattr(f, name) for f in fragments], dim=-1 if name.startswith("next") else 1)  # noqa: E731
        episodes, offset = [], 0
        for f in fragments:
            episodes += [{**e, "row": e["row"] + offset} for e in f.episodes]
            offset += f.rewards.shape[1]
        return Fragment({k: torch.cat([f.inputs[k] for f in fragments], dim=1) for k in fragments[0].inputs},
                        *(cat(n) for n in ("raw_state", "actions", "logprobs", "rewards", "dones", "values",
                                           "next_value", "next_done")),
                        sorted(episodes, key=lambda e: (e["step"], e["row"])),
                        max(f.starts_bound for f in fragments))


def sample_action(actor, x: dict[str, torch.Tensor], log_std: torch.Tensor, normalizer: Normalizer,
                  gripper: str) -> tuple[torch.Tensor, ActionDistribution, torch.Tensor, torch.Tensor]:
    """As training acts: (the actor's output, its distribution, a sampled action in the actor's space, the env
    action made of it) for the normalized inputs `x`."""
    binary = gripper == "binary"
    with torch.no_grad():
        out = actor(x)
        dist = ActionDistribution(out, log_std, binary)
        action = dist.sample()
    return out, dist, action, env_action(action, normalizer, gripper, close=action[:, -1] if binary else None)


def episode_outcome(success: bool, fail_cause: int, truncated: bool) -> str:
    """A finished training episode's outcome: "success", the failure cause's label (`envs.checks.FailureCause`), or
    "truncated" (the time limit)."""
    from ..envs.checks import FailureCause

    if success:
        return "success"
    if fail_cause:
        return FailureCause(fail_cause).label
    return "truncated" if truncated else "ended"


def state_dim(env: SkillEnv, obs: dict, inputs: InputSpec) -> int:
    """The actor's state width for `inputs` on this env (observation `obs`)."""
    observer = ActorObserver({"inputs": inputs.as_dict(), "cameras": [], "image_size": 0})
    return observer.observe(env.env.unwrapped, obs)["state"].shape[-1]


class Collector:
    """Collects windows from one `SkillEnv`, starting from its first reset's `obs`/`info`, with the policy it is
    given (the learner's own modules in its process, a copy loaded with `load_policy` in a worker). Episodes run on
    across windows."""

    def __init__(self, env: SkillEnv, obs: dict, info: dict, inputs: InputSpec, model: dict, actor, critic,
                 log_std: torch.Tensor, normalizer: Normalizer):
        from .rewards import potential

        self.env, self.inputs, self.model = env, inputs, model
        self.actor, self.critic, self.log_std, self.normalizer = actor, critic, log_std, normalizer
        # the actor's inputs, the window's tensors and the episode sums live on the env's device, as the networks do
        self.device = env.device
        self.observer = ActorObserver(model, self.device)
        self.obs, self.info = obs, info
        n = env.n
        self.next_done = torch.zeros(n, device=self.device)
        self.prev_phi = potential(env.config.skill, self.info)
        self.ep_return = torch.zeros(n, device=self.device)
        self.ep_length = torch.zeros(n, dtype=torch.long, device=self.device)
        self.ep_peak = self.prev_phi.clone().float()  # the episode's highest potential: how far it got

    def load_policy(self, policy: dict) -> None:
        """A worker's copy of the learner's policy: `{"actor", "critic", "log_std", "normalizer"}`."""
        self.actor.load_state_dict(policy["actor"])
        self.critic.load_state_dict(policy["critic"])
        with torch.no_grad():
            self.log_std.copy_(policy["log_std"])
        self.normalizer.load_state_dict(policy["normalizer"])

    def raw_inputs(self, keep: bool = True) -> dict[str, torch.Tensor]:
        """The actor's raw inputs for the current observation; `keep`: it enters the frame history."""
        return self.observer.observe(self.env.env.unwrapped, self.obs, keep)

    def _normed(self, x: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        return {**x, "state": self.normalizer.state(x["state"])}

    def _bootstrap_value(self) -> torch.Tensor:
        with torch.no_grad():
            return self.critic(self._normed(self.raw_inputs(keep=False)))[:, 0]

    def collect(self, steps: int, gamma: float) -> Fragment:
        from .rewards import potential, reward

        skill, env, device = self.env.config.skill, self.env, self.env.device
        rows = []
        episodes = []
        for t in range(steps):
            raw = self.raw_inputs()
            x = self._normed(raw)
            with torch.no_grad():
                value = self.critic(x)[:, 0]
            _, dist, action, sent = sample_action(self.actor, x, self.log_std, self.normalizer, self.model["gripper"])
            sent = self.observer.to_env(sent, self.obs)
            self.obs, _, terminated, truncated, self.info = env.env.step(sent.to(device))
            r, phi, _ = reward(skill, self.info, self.prev_phi, sent.to(device), kind=env.config.reward, gamma=gamma)
            r = r.float()
            terminated, truncated = terminated.bool(), truncated.bool()
            cut = truncated & ~terminated
            if cut.any():  # host reads of a step: whether an episode was cut, whether one ended  # a time limit is not an end of the task: bootstrap from the last state's value
                r = r + gamma * self._bootstrap_value() * cut
            rows.append({"inputs": x, "raw_state": raw["state"], "actions": action, "logprobs": dist.log_prob(action),
                         "rewards": r, "dones": self.next_done, "values": value})
            self.ep_return += r
            self.ep_length += 1
            self.ep_peak = torch.maximum(self.ep_peak, phi.float())
            done = terminated | truncated
            self.next_done = done.float()
            self.prev_phi = phi
            if done.any():
                success = self.info["success"].cpu().bool()
                causes = self.info["fail_cause"].cpu().tolist() if "fail_cause" in self.info else None
                idx = done.nonzero()[:, 0]
                episodes += [{"step": t, "row": i, "success": bool(success[i]), "return": float(self.ep_return[i]),
                              "length": int(self.ep_length[i]), "outcome": episode_outcome(
                                  bool(success[i]), causes[i] if causes else 0, bool(truncated[i])),
                              "peak_potential": float(self.ep_peak[i])} for i in idx.tolist()]
                self.ep_return[done], self.ep_length[done] = 0.0, 0
                self.obs, self.info = env.reset_some(idx)
                self.observer.reset(idx)
                self.prev_phi = torch.where(done, potential(skill, self.info), self.prev_phi)
                self.ep_peak = torch.where(done, self.prev_phi.float(), self.ep_peak)
        stacked = {name: torch.stack([row[name] for row in rows]) for name in rows[0] if name != "inputs"}
        inputs = {k: torch.stack([row["inputs"][k] for row in rows]) for k in rows[0]["inputs"]}
        return Fragment(inputs, **stacked, next_value=self._bootstrap_value(), next_done=self.next_done.clone(),
                        episodes=episodes, starts_bound=env.starts_bound)
