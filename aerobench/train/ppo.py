"""`aerobench train ppo`: PPO on one skill env, from scratch or from a BC checkpoint (CleanRL style, one file).

Spec, "PPO Training": a Gaussian actor with a separate critic, generalized advantage estimation and clipped policy
updates; rewards from task progress and success with penalties for undesirable actions and contacts
(`aerobench.train.rewards`); optionally initialised from a BC policy with critic warm-up and imitation
regularization. The spec's reference configuration is the default: 64-step rollout windows, gamma 0.97, clip 0.2.
The spec states no other hyper-parameter; the rest are CleanRL's `ppo_continuous_action.py` defaults, except 4
minibatches (64 samples per window on one CPU env) and a constant learning rate by default: CleanRL anneals it to 0 at
the end of the budget, which would tie the schedule to a budget that a resumed run may raise, so the annealing here is
`--lr-decay-steps N`, to 0 at N env steps whatever the budget.

Read top to bottom: config -> env(s) -> networks -> loop (rollout window, GAE, clipped update, log, checkpoint).
The rollout window (`aerobench.train.ppo_rollout.Collector`) steps the envs with the current policy: `num_envs` in
one batched scene on physx_cuda; on physx_cpu one env here, or with `--num-envs K` one env per rollout worker
process (`aerobench.train.rollout_workers`), each acting with a copy of the policy and returning its whole window.
Actions are sampled in the actor's normalized action space and sent to the env unnormalized and clamped to [-1, 1].
Every finished training episode is appended to `OUT/train_episodes.jsonl`. A checkpoint is written after a window
(every `save_every` windows and at the end); a resumed run continues from the last one with fresh episodes (the
ones in flight at the interrupt are dropped, their interactions stay counted) and drops the log lines written
after it, so no window is lost or counted twice.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import torch
from torch import nn
from torch.nn import functional as F

from ..envs.observations import task_state_fields
from ..policies.inputs import InputSpec
from ..policies.learned import (
    GRIPPER_MODES,
    Normalizer,
    identity_stats,
    load_actor,
    load_weights,
    make_actor,
    make_critic,
    model_spec,
    read_config,
    recover_checkpoint,
    resolve_checkpoint,
    save_checkpoint,
)
from ..policies.provenance import TrainingStarts, read_starts
from ..threads import torch_threads
from .common import (
    ScalarLog,
    check_resumable,
    config_dict,
    load_train_state,
    seed_everything,
    truncate_jsonl,
)
from .ppo_rollout import RESET_SEED_STRIDE, ActionDistribution, Collector, Fragment, SkillEnv
from .ppo_rollout import state_dim as rollout_state_dim
from .rewards import REWARD_KINDS
from .rollout_workers import ProcessWorkers, RayWorkers

EPISODES_FILE = "train_episodes.jsonl"
SUCCESS_WINDOW = 100  # charts/success_rate: the last 100 finished episodes
SIM_BACKENDS = ("physx_cpu", "physx_cuda")
# Options that may change when a run is resumed: the budget, the bookkeeping, and `out` (a run folder may be moved).
RESUMABLE_CHANGES = ("total_steps", "save_every", "progress", "threads", "ray", "out")


@dataclass
class PPOConfig:
    setting: str = field(default=None, metadata={"help": "TidyHouse, PrepareGroceries, PackageDelivery, LongHorizonRearrangement"})
    skill: str = field(default=None, metadata={"help": "pick, place, nav, open or close"})
    out: str = field(default=None, metadata={"help": "run folder: checkpoint/, scalars.jsonl, train_episodes.jsonl"})
    objects: tuple[str, ...] | None = field(default=None, metadata={"help": "objects, round-robin over episodes "
                                                                            "(default: the setting's, sampled)"})
    total_steps: int = field(default=1_000_000, metadata={"help": "env steps in total (a resumed run continues to this)"})
    seed: int = field(default=0, metadata={"help": "seed of the networks, the action noise and the episodes"})
    num_envs: int = field(default=1, metadata={"help": "parallel envs (physx_cuda: one batched scene; physx_cpu: one "
                                                      "worker process each)"})
    sim_backend: str = field(default="physx_cpu", metadata={"help": "physx_cpu or physx_cuda"})
    init_bc: str | None = field(default=None, metadata={"help": "BC checkpoint to initialise the actor (and its "
                                                                 "normalization) from"})
    num_steps: int = field(default=64, metadata={"help": "rollout window per env (spec: 64)"})
    gamma: float = field(default=0.97, metadata={"help": "discount (spec: 0.97)"})
    reward: str = field(default="potential", metadata={"help": "potential (progress as differences of a potential) "
                        "or dense (progress paid at every step; aerobench.train.rewards)"})
    clip_coef: float = field(default=0.2, metadata={"help": "policy clip (spec: 0.2)"})
    gae_lambda: float = field(default=0.95, metadata={"help": "GAE lambda"})
    learning_rate: float = field(default=3e-4, metadata={"help": "Adam learning rate"})
    lr_decay_steps: int = field(default=0, metadata={"help": "env step at which the learning rate reaches 0, decaying "
                                "linearly, set before each window (CleanRL's annealing; 0: constant)"})
    lr_decay_start: int = field(default=0, metadata={"help": "env step at which that decay begins (constant before: "
                                "anneal once the skill is found)"})
    lr_decay_at_success: float = field(default=0.0, metadata={"help": "instead of a fixed start: begin the decay after "
                                       "the first window at which this share of the last 100 training episodes "
                                       "succeeded (0: off; needs --lr-decay-length)"})
    lr_decay_length: int = field(default=0, metadata={"help": "with --lr-decay-at-success: env steps from that "
                                 "window to a rate of 0"})
    update_epochs: int = field(default=10, metadata={"help": "epochs over each window"})
    num_minibatches: int = field(default=4, metadata={"help": "minibatches per epoch"})
    ent_coef: float = field(default=0.0, metadata={"help": "entropy bonus"})
    vf_coef: float = field(default=0.5, metadata={"help": "value loss weight"})
    max_grad_norm: float = field(default=0.5, metadata={"help": "gradient clip"})
    norm_adv: bool = field(default=True, metadata={"help": "normalize advantages per minibatch"})
    clip_vloss: bool = field(default=True, metadata={"help": "clip the value loss"})
    target_kl: float | None = field(default=None, metadata={"help": "stop a window's epochs beyond this KL"})
    hidden: tuple[int, ...] = field(default=(256, 256), metadata={"help": "MLP hidden sizes (from scratch)"})
    state_fields: tuple[str, ...] = field(default=(), metadata={"help": "from scratch: proprio state fields to read "
                                          "(default none); --init-bc keeps the BC model's inputs"})
    task_fields: tuple[str, ...] | None = field(default=None, metadata={"help": "from scratch: task state fields to "
                                                "read (default: all of the platform's)"})
    gripper: str = field(default="binary", metadata={"help": "from scratch: binary (Bernoulli open/close) or "
                         "continuous (Gaussian) gripper; --init-bc keeps the BC model's head"})
    init_log_std: float = field(default=-0.5, metadata={"help": "initial log std of the Gaussian (normalized actions)"})
    critic_warmup_steps: int = field(default=0, metadata={"help": "env steps at the start that train only the critic"})
    bc_coef: float = field(default=0.0, metadata={"help": "imitation regularization: weight of the MSE to the "
                                                          "frozen BC actor (needs --init-bc)"})
    bc_decay_steps: int = field(default=0, metadata={"help": "env steps over which bc_coef decays linearly to 0 "
                                                             "(0: constant)"})
    max_episode_steps: int | None = field(default=None, metadata={"help": "episode length (default: the env's)"})
    platform: str | None = field(default=None, metadata={"help": "gripper or arm (default: the skill's)"})
    controller: str = field(default="payload-aware", metadata={"help": "payload-aware or nominal"})
    save_every: int = field(default=10, metadata={"help": "checkpoint every N windows (and at the end)"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})
    threads: int = field(default=1, metadata={"help": "torch CPU threads (1 is fastest for these small networks)"})
    ray: str | None = field(default=None, metadata={"const": "local", "help": "[ADDRESS] physx_cpu: the --num-envs envs as Ray "
                            "actors (rollout workers) instead of local worker processes: --ray alone starts a local "
                            "Ray runtime, --ray HOST:PORT (or auto) joins a cluster; the learner stays here"})

    def __post_init__(self):
        from ..envs.checker import SKILL_ENV_IDS
        from ..envs.tasks import get_setting

        if not self.setting or not self.skill or not self.out:
            raise ValueError("PPOConfig needs setting=, skill= and out=")
        self.hidden = tuple(self.hidden)
        self.objects = tuple(self.objects) if self.objects else None
        setting = get_setting(self.setting)  # unknown settings list the valid ones
        if self.skill not in SKILL_ENV_IDS:
            raise ValueError(f"unknown skill {self.skill!r}; PPO trains one of: {', '.join(SKILL_ENV_IDS)}")
        setting.check_skill(self.skill)
        for obj in self.objects or ():
            setting.check_object(obj)
        if self.sim_backend not in SIM_BACKENDS:
            raise ValueError(f"unknown --sim-backend {self.sim_backend!r}; valid: {', '.join(SIM_BACKENDS)}")
        for name in ("total_steps", "num_envs", "num_steps", "update_epochs", "num_minibatches", "save_every", "threads"):
            if not (isinstance(getattr(self, name), int) and getattr(self, name) > 0):
                raise ValueError(f"--{name.replace('_', '-')} must be a positive integer, got {getattr(self, name)}")
        if self.ray is not None and (self.sim_backend != "physx_cpu" or self.num_envs < 2):
            raise ValueError("--ray runs the --num-envs physx_cpu envs as Ray actors: give --num-envs 2 or more "
                             "(physx_cuda batches its envs in one process)")
        if (self.num_steps * self.num_envs) % self.num_minibatches:
            raise ValueError(f"--num-minibatches ({self.num_minibatches}) must divide num_steps x num_envs "
                             f"({self.num_steps * self.num_envs})")
        if not (0 < self.gamma <= 1 and 0 <= self.gae_lambda <= 1 and self.clip_coef > 0 and self.learning_rate > 0):
            raise ValueError("need 0 < gamma <= 1, 0 <= gae_lambda <= 1, clip_coef > 0 and learning_rate > 0")
        if min(self.bc_coef, self.critic_warmup_steps, self.bc_decay_steps, self.lr_decay_steps, self.lr_decay_start) < 0:
            raise ValueError("--bc-coef, --critic-warmup-steps, --bc-decay-steps, --lr-decay-steps and --lr-decay-start "
                             "must not be negative")
        if not 0 <= self.lr_decay_at_success <= 1 or self.lr_decay_length < 0:
            raise ValueError("--lr-decay-at-success must lie in [0, 1] and --lr-decay-length must not be negative")
        if bool(self.lr_decay_at_success) != bool(self.lr_decay_length):
            raise ValueError("--lr-decay-at-success and --lr-decay-length go together: the share of successes that "
                             "starts the decay, and the env steps it lasts")
        if self.lr_decay_at_success and (self.lr_decay_steps or self.lr_decay_start):
            raise ValueError("--lr-decay-at-success starts the decay when training succeeds; drop --lr-decay-steps and "
                             "--lr-decay-start, which fix it by the step count")
        if self.lr_decay_start and not self.lr_decay_start < self.lr_decay_steps:
            raise ValueError(f"--lr-decay-start ({self.lr_decay_start}) must be below --lr-decay-steps "
                             f"({self.lr_decay_steps}), the step at which the rate reaches 0")
        if (self.bc_coef > 0 or self.critic_warmup_steps > 0) and not self.init_bc:
            raise ValueError("--bc-coef and --critic-warmup-steps apply to a BC-initialised run: add --init-bc DIR")
        if self.reward not in REWARD_KINDS:
            raise ValueError(f"--reward must be one of {', '.join(REWARD_KINDS)}, got {self.reward!r}")
        if self.reward == "dense" and self.gamma >= 1:
            raise ValueError("--reward dense pays a success what staying at the goal is worth: it needs --gamma below 1")
        if self.gripper not in GRIPPER_MODES:
            raise ValueError(f"--gripper must be one of {', '.join(GRIPPER_MODES)}, got {self.gripper!r}")
        self.state_fields = tuple(self.state_fields)
        self.task_fields = None if self.task_fields is None else tuple(self.task_fields)
        self.input_spec(with_arm=True)  # unknown field names fail here
        if self.init_bc:
            resolve_checkpoint(self.init_bc, "bc")  # a missing checkpoint fails before the env is built
        from ..envs.control.payload import ControllerMode
        from ..envs.platforms import get_platform

        ControllerMode.parse(self.controller)  # unknown names list the valid ones
        if self.platform:
            get_platform(self.platform)
        if self.max_episode_steps is not None and self.max_episode_steps < 1:
            raise ValueError(f"--max-episode-steps must be a positive integer, got {self.max_episode_steps}")

    @property
    def batch_size(self) -> int:
        return self.num_steps * self.num_envs

    def input_spec(self, with_arm: bool) -> InputSpec:
        task = self.task_fields if self.task_fields is not None else tuple(n for n, _ in task_state_fields(with_arm))
        return InputSpec(state_fields=self.state_fields, task_fields=task)


def imitation_loss(out: torch.Tensor, teacher: torch.Tensor, binary: bool) -> torch.Tensor:
    """Distance of the actor's output to the frozen BC actor's: MSE of the continuous means, and (binary gripper)
    the cross-entropy to the teacher's close probability."""
    if not binary:
        return (out - teacher).pow(2).mean()
    mse = (out[:, :-1] - teacher[:, :-1]).pow(2).mean()
    return mse + F.binary_cross_entropy_with_logits(out[:, -1], torch.sigmoid(teacher[:, -1]))


class RunningMeanStd:
    """Running state mean / variance (Welford over batches), for runs from scratch (CleanRL normalizes observations)."""

    def __init__(self, dim: int, device: torch.device | str = "cpu"):
        self.mean, self.var, self.count = torch.zeros(dim, device=device), torch.ones(dim, device=device), 1e-4

    def update(self, x: torch.Tensor) -> None:
        mean, var, n = x.mean(0), x.var(0, unbiased=False), x.shape[0]
        delta, total = mean - self.mean, self.count + n
        self.mean = self.mean + delta * n / total
        self.var = (self.var * self.count + var * n + delta.pow(2) * self.count * n / total) / total
        self.count = total

    def state(self) -> dict:
        return {"mean": self.mean.cpu(), "var": self.var.cpu(), "count": self.count}

    def load(self, state: dict) -> None:
        device = self.mean.device
        self.mean, self.var, self.count = state["mean"].to(device), state["var"].to(device), state["count"]


def linear_decay(step: int, steps: int, start: int = 0) -> float:
    """A weight's factor at `step`: 1 up to `start`, falling linearly to 0 at `steps` (0: no decay)."""
    return min(1.0, max(0.0, 1.0 - (step - start) / (steps - start))) if steps else 1.0


def lr_factor(config: PPOConfig, step: int, decay_from: int | None) -> float:
    """The learning rate's factor at `step`: the fixed schedule (`--lr-decay-start/-steps`), or the decay that began
    at `decay_from`, the step at which training success first reached `--lr-decay-at-success` (None: not yet)."""
    if not config.lr_decay_at_success:
        return linear_decay(step, config.lr_decay_steps, config.lr_decay_start)
    return 1.0 if decay_from is None else linear_decay(step, decay_from + config.lr_decay_length, decay_from)


def success_triggered(config: PPOConfig, recent: list[bool]) -> bool:
    """Whether the last SUCCESS_WINDOW training episodes reach `--lr-decay-at-success` (a full window is needed, so a
    lucky first episode does not start the decay)."""
    return bool(config.lr_decay_at_success) and len(recent) == SUCCESS_WINDOW and \
        sum(recent) >= config.lr_decay_at_success * SUCCESS_WINDOW - 1e-9  # 0.07 x 100 is 7.000000000000001


def _inputs_at(storage: dict[str, torch.Tensor], index) -> dict[str, torch.Tensor]:
    return {k: v[index] for k, v in storage.items()}


def gae(rewards: torch.Tensor, dones: torch.Tensor, values: torch.Tensor, next_value: torch.Tensor,
        next_done: torch.Tensor, gamma: float, gae_lambda: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Generalized advantage estimation over a `(T, N)` window: (advantages, returns)."""
    T, N = rewards.shape
    advantages, last = torch.zeros((T, N), device=rewards.device), torch.zeros(N, device=rewards.device)
    for t in reversed(range(T)):
        next_nonterminal = 1.0 - (next_done if t == T - 1 else dones[t + 1])
        next_values = next_value if t == T - 1 else values[t + 1]
        delta = rewards[t] + gamma * next_values * next_nonterminal - values[t]
        advantages[t] = last = delta + gamma * gae_lambda * next_nonterminal * last
    return advantages, advantages + values


def ppo_update(config: PPOConfig, batch: dict, actor: nn.Module, critic: nn.Module, log_std: nn.Parameter,
               optimizer: torch.optim.Optimizer, binary: bool, bc_actor: nn.Module | None, bc_coef: float,
               warmup: bool) -> dict[str, float]:
    """`update_epochs` passes of clipped policy and value updates over one window's flat `batch`; returns the mean of
    each loss statistic. Statistics stay tensors until the end: one host read per epoch (the target-KL check)
    instead of seven per minibatch."""
    n = len(batch["logprobs"])
    minibatch = config.batch_size // config.num_minibatches
    stats = {k: [] for k in ("policy_loss", "value_loss", "entropy", "old_approx_kl", "approx_kl", "clipfrac", "imitation")}
    for _ in range(config.update_epochs):
        order = torch.randperm(n, device=batch["logprobs"].device)
        for start in range(0, n, minibatch):
            mb = order[start : start + minibatch]
            mb_inputs = _inputs_at(batch["inputs"], mb)
            pred = actor(mb_inputs)
            dist = ActionDistribution(pred, log_std, binary)
            new_logprob, entropy = dist.log_prob(batch["actions"][mb]), dist.entropy()
            log_ratio = new_logprob - batch["logprobs"][mb]
            ratio = log_ratio.exp()
            with torch.no_grad():
                stats["old_approx_kl"].append((-log_ratio).mean())
                stats["approx_kl"].append(((ratio - 1) - log_ratio).mean())
                stats["clipfrac"].append(((ratio - 1.0).abs() > config.clip_coef).float().mean())
            adv = batch["advantages"][mb]
            if config.norm_adv and len(mb) > 1:
                adv = (adv - adv.mean()) / (adv.std() + 1e-8)
            pg_loss = torch.max(-adv * ratio, -adv * ratio.clamp(1 - config.clip_coef, 1 + config.clip_coef)).mean()
            new_value = critic(mb_inputs)[:, 0]
            old_value, target = batch["values"][mb], batch["returns"][mb]
            if config.clip_vloss:
                clipped = old_value + (new_value - old_value).clamp(-config.clip_coef, config.clip_coef)
                v_loss = 0.5 * torch.max((new_value - target).pow(2), (clipped - target).pow(2)).mean()
            else:
                v_loss = 0.5 * (new_value - target).pow(2).mean()
            imitation = torch.zeros((), device=pred.device)
            if bc_actor is not None and bc_coef > 0:
                with torch.no_grad():
                    teacher = bc_actor(mb_inputs)
                imitation = imitation_loss(pred, teacher, binary)
            loss = config.vf_coef * v_loss
            if not warmup:  # critic warm-up: the BC actor stays as it is while the critic learns its values
                loss = loss + pg_loss - config.ent_coef * entropy.mean() + bc_coef * imitation
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_([*actor.parameters(), *critic.parameters(), log_std], config.max_grad_norm)
            optimizer.step()
            for name, value in (("policy_loss", pg_loss), ("value_loss", v_loss), ("entropy", entropy.mean()),
                                ("imitation", imitation)):
                stats[name].append(value.detach())
        if config.target_kl is not None and stats["approx_kl"][-1].item() > config.target_kl:
            break
    return {name: float(torch.stack(values).double().mean()) for name, values in stats.items()}


def train_ppo(config: PPOConfig) -> Path:
    """Train (or resume) PPO; returns the checkpoint folder (`--policy ppo --checkpoint DIR`)."""
    with torch_threads(config.threads):
        return _train_ppo(config)


def _resume(config: PPOConfig, out: Path, current: dict) -> tuple[Path | None, dict | None]:
    """The run's last checkpoint and train state (None, None for a new run), checked against this config."""
    checkpoint = recover_checkpoint(out)
    if checkpoint is None:
        return None, None
    saved = read_config(checkpoint)
    if saved["algorithm"] != "ppo":
        raise ValueError(f"{out} holds a {saved['algorithm']} run; choose another --out")
    # a run saved before `--reward` (or the `--lr-decay-*` options) existed trained with the potential reward (and
    # a constant learning rate)
    old_defaults = {"reward": "potential", "lr_decay_steps": 0, "lr_decay_start": 0, "lr_decay_at_success": 0.0,
                    "lr_decay_length": 0}
    check_resumable({**old_defaults, **saved["train"]}, current, out, RESUMABLE_CHANGES)
    return checkpoint, load_train_state(checkpoint, out)


def _train_ppo(config: PPOConfig) -> Path:
    from ..envs.platforms import get_platform

    out = Path(config.out)
    current = config_dict(config)
    checkpoint, train_state = _resume(config, out, current)
    if train_state is not None and train_state["global_step"] >= config.total_steps:
        return checkpoint
    global_step = train_state["global_step"] if train_state else 0
    iteration = train_state["iteration"] if train_state else 0
    episodes_done = train_state["episodes"] if train_state else 0
    lr_decay_from = train_state.get("lr_decay_from") if train_state else None

    # ── networks ──
    seed_everything(config.seed)
    bc_actor = None
    if config.init_bc:
        bc_config, bc_actor, bc_norm = load_actor(resolve_checkpoint(config.init_bc, "bc"))
        if bc_config["algorithm"] != "bc":
            raise ValueError(f"--init-bc {config.init_bc} holds a {bc_config['algorithm']} checkpoint, not bc")
        model, stats = bc_config["model"], bc_norm.as_dict()
    obs_mode = "rgbd" if config.init_bc and model["cameras"] else "state_dict"
    # ── env(s): in this process (physx_cuda's batch, or one physx_cpu env) or one worker process each ──
    episodes_started = train_state["episodes_started"] if train_state else 0
    workers = None
    if config.sim_backend == "physx_cpu" and config.num_envs > 1:  # one env per process: K rollout workers
        if obs_mode != "state_dict":
            raise ValueError("--num-envs > 1 on physx_cpu trains state-only actors; use --num-envs 1 for a camera BC "
                             "init, or --sim-backend physx_cuda")
        workers = (RayWorkers(config, obs_mode, config.num_envs, episodes_started, config.ray) if config.ray
                   else ProcessWorkers(config, obs_mode, config.num_envs, episodes_started))
        platform = get_platform(workers.platform_name)
    else:
        env = SkillEnv(config, obs_mode, config.num_envs, episodes_started=episodes_started)
        first_obs, first_info = env.reset_all()
        platform = env.platform
    action_dim = platform.action_dim
    with_arm = platform.arm is not None
    inputs = InputSpec.from_dict(model["inputs"]) if bc_actor is not None else config.input_spec(with_arm)
    state_dim = workers.call("state_dim", inputs.as_dict())[0] if workers else rollout_state_dim(env, first_obs, inputs)
    if bc_actor is None:
        model = model_spec(state_dim, action_dim, config.hidden, inputs, gripper=config.gripper)
        stats = identity_stats(state_dim, action_dim)
    elif (model["state_dim"], model["action_dim"]) != (state_dim, action_dim):
        raise ValueError(f"--init-bc {config.init_bc} was trained for state {model['state_dim']} / action "
                         f"{model['action_dim']}; this env has {state_dim} / {action_dim} (same platform needed)")
    binary = model["gripper"] == "binary"
    # the networks act and learn where the envs run: physx_cuda's batch on its GPU (no per-step copy of the window to
    # the host), physx_cpu on the CPU (rollout workers act with CPU copies)
    device = env.device if workers is None else torch.device("cpu")
    actor, critic = make_actor(model).to(device), make_critic(model).to(device)
    if bc_actor is not None:
        bc_actor.to(device)
        actor.load_state_dict(bc_actor.state_dict())
        bc_actor.requires_grad_(False)
    log_std = nn.Parameter(torch.full((action_dim - binary,), float(config.init_log_std), device=device))
    normalizer = Normalizer(stats).to(device)
    obs_rms = RunningMeanStd(state_dim, device) if bc_actor is None else None  # a BC actor keeps its stats
    optimizer = torch.optim.Adam([*actor.parameters(), *critic.parameters(), log_std], lr=config.learning_rate, eps=1e-5)
    if train_state is not None:
        weights = load_weights(checkpoint)
        actor.load_state_dict({k.removeprefix("actor."): v for k, v in weights.items() if k.startswith("actor.")})
        critic.load_state_dict({k.removeprefix("critic."): v for k, v in weights.items() if k.startswith("critic.")})
        with torch.no_grad():
            log_std.copy_(weights["log_std"])
        optimizer.load_state_dict(train_state["optimizer"])
        normalizer = Normalizer(json.loads((checkpoint / "normalization.json").read_text())).to(device)
        if obs_rms is not None:
            obs_rms.load(train_state["obs_rms"])
        torch.set_rng_state(train_state["torch_rng"])
        if device.type == "cuda" and "cuda_rng" in train_state:  # actions are sampled with the GPU's generator there
            torch.cuda.set_rng_state(train_state["cuda_rng"], device)
    meta = {"algorithm": "ppo", "model": model, "train": current, "platform": platform.name}
    if workers is None:  # the collector acts with the learner's own modules
        collector = Collector(env, first_obs, first_info, inputs, model, actor, critic, log_std, normalizer)

    def collect() -> Fragment:
        """One window of every env with the current policy (a worker acts with a copy, its noise seeded per window)."""
        if workers is None:
            return collector.collect(config.num_steps, config.gamma)
        policy = {"actor": actor.state_dict(), "critic": critic.state_dict(), "log_std": log_std.detach(),
                  "normalizer": normalizer.state_dict()}
        return Fragment.join(workers.call("collect", model, policy, config.num_steps, config.gamma,
                                          config.seed * RESET_SEED_STRIDE + iteration))

    bc_starts = read_starts(resolve_checkpoint(config.init_bc, "bc")) if config.init_bc else TrainingStarts()

    def starts() -> TrainingStarts:
        """The env episodes this run started (seeds seed * stride + k, k below the bound), and its BC data's."""
        own = TrainingStarts(ranges=[(config.setting, config.skill, config.seed * RESET_SEED_STRIDE, episodes_started)],
                             sources=[f"{config.out} (PPO episodes, start indices below {episodes_started})"])
        own.add(bc_starts)
        return own

    def save() -> Path:
        weights = {**{f"actor.{k}": v.cpu() for k, v in actor.state_dict().items()},
                   **{f"critic.{k}": v.cpu() for k, v in critic.state_dict().items()}, "log_std": log_std.detach().cpu()}
        state = {"global_step": global_step, "iteration": iteration, "episodes": episodes_done,
                 "episodes_started": episodes_started, "optimizer": optimizer.state_dict(),
                 "torch_rng": torch.get_rng_state(), "obs_rms": obs_rms.state() if obs_rms else None,
                 "lr_decay_from": lr_decay_from,
                 **({"cuda_rng": torch.cuda.get_rng_state(device)} if device.type == "cuda" else {})}
        return save_checkpoint(out, meta, weights, normalizer.as_dict(), state, starts())

    T, N = config.num_steps, config.num_envs
    out.mkdir(parents=True, exist_ok=True)
    episodes_path = out / EPISODES_FILE
    # the success window carries over a resume (it decides --lr-decay-at-success)
    recent = [row["success"] for row in truncate_jsonl(episodes_path, "global_step", global_step)[-SUCCESS_WINDOW:]]
    episode_log = open(episodes_path, "a")
    log = ScalarLog(out, global_step)
    bar = None
    if config.progress:
        from tqdm import tqdm

        bar = tqdm(total=config.total_steps, initial=global_step, unit="step", desc=f"ppo {config.skill}", dynamic_ncols=True)

    path = checkpoint
    while global_step < config.total_steps:
        iteration += 1
        t0, window_start = time.perf_counter(), global_step
        # from the step count (and the trigger's step, kept in the train state), so a resumed run keeps its schedule
        optimizer.param_groups[0]["lr"] = config.learning_rate * lr_factor(config, global_step, lr_decay_from)
        # ── rollout window: (T, N) samples ──
        window = collect()
        global_step += T * N
        episodes_started = max(episodes_started, window.starts_bound)
        for episode in window.episodes:
            episodes_done += 1
            step = window_start + (episode["step"] + 1) * N
            recent = (recent + [episode["success"]])[-SUCCESS_WINDOW:]
            episode_log.write(json.dumps({"global_step": step, "episode": episodes_done, **{
                k: episode[k] for k in ("success", "return", "length", "outcome", "peak_potential")}}) + "\n")
            log.add("charts/episodic_return", episode["return"], step)
            log.add("charts/episodic_length", episode["length"], step)
        if lr_decay_from is None and success_triggered(config, recent):
            lr_decay_from = global_step  # the rate falls linearly from here (the window after next is the first lowered)
            log.add("charts/lr_decay_from", global_step, global_step)
        if obs_rms is not None:  # from scratch: state statistics follow what the policy sees
            obs_rms.update(window.raw_state.reshape(-1, state_dim))
            normalizer.state_mean.copy_(obs_rms.mean)
            normalizer.state_std.copy_(obs_rms.var.sqrt().clamp_min(1e-2))

        # ── GAE, then the clipped update over the window's (T * N) samples ──
        advantages, returns = gae(window.rewards, window.dones, window.values, window.next_value, window.next_done,
                                  config.gamma, config.gae_lambda)
        batch = {"inputs": {k: v.reshape(T * N, *v.shape[2:]) for k, v in window.inputs.items()},
                 "actions": window.actions.reshape(T * N, -1), "logprobs": window.logprobs.reshape(-1),
                 "advantages": advantages.reshape(-1), "returns": returns.reshape(-1),
                 "values": window.values.reshape(-1)}
        stats = ppo_update(config, batch, actor, critic, log_std, optimizer, binary,
                           bc_actor,
                           bc_coef=config.bc_coef * linear_decay(global_step, config.bc_decay_steps),
                           warmup=global_step <= config.critic_warmup_steps)
        b_returns, b_values = batch["returns"], batch["values"]

        # ── log, checkpoint ──
        var_y = b_returns.var()
        explained = math.nan if var_y == 0 else float(1 - (b_returns - b_values).var() / var_y)
        for name, value in stats.items():
            log.add(f"losses/{name}", value, global_step)
        if math.isfinite(explained):
            log.add("losses/explained_variance", explained, global_step)
        log.add("charts/learning_rate", optimizer.param_groups[0]["lr"], global_step)
        log.add("charts/action_std", float(log_std.detach().exp().mean()), global_step)
        log.add("charts/SPS", (global_step - window_start) / (time.perf_counter() - t0), global_step)
        if recent:
            log.add("charts/success_rate", sum(recent) / len(recent), global_step)
        if bar is not None:
            bar.update(global_step - window_start)
            bar.set_postfix_str(f"episodes {episodes_done}, success {sum(recent)}/{len(recent)}")
        if iteration % config.save_every == 0 or global_step >= config.total_steps:
            episode_log.flush()
            log.flush()
            path = save()
    episode_log.close()
    log.close()
    (workers if workers is not None else env).close()
    if bar is not None:
        bar.close()
    return path
