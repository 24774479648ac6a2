"""The one rollout runner: env + policy -> per-step signals -> annotation -> episode records, handed to a sink.

Data generation (`aerobench generate`) and evaluation (`aerobench eval`) both run it; they differ only in the policy
and the sink. Episodes are planned up front (`plan_episodes`): episode i has a fixed seed, skill and object, so
the same command gives the same episodes, `--shard i/k` takes the i-th of k contiguous blocks of the plan (so the
merged shards are in plan order), and a rerun skips what its sink already holds. physx_cpu runs one env per process (use shards for parallelism); with physx_cuda, `num_envs`
episodes of the same skill run as one batch.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cached_property

import gymnasium as gym
import numpy as np
import torch

from ..annotation import EpisodeRecord, categorize, cut_segments
from ..envs.base_env import check_physx_solver, default_physx_solver, freeze_process_heap
from ..envs.checker import SKILL_ENV_IDS
from ..envs.conditions.registry import parse_condition_names, resolve_condition
from ..envs.rendering import DEFAULT_RENDERING, check_rendering
from ..envs.tasks import SKILLS, get_setting
from ..policies import make_policy
from ..policies.remote import PolicyServerSpec
from .batch import BatchStatus, Wave, per_env_signals
from .chained import ChainedPolicy, ChainMonitor, checkpoint_for, split_checkpoints
from .episode import CAMERAS, EVENT_FLAGS, EpisodeData, EpisodeSink
from .noise import ActionNoise, check_action_noise
from .realtime import RealtimePolicy, RealtimeSpec

THIRD_PERSON = "third_person"
SEED_STRIDE = 1_000_003  # episode seed = base seed * stride + episode index: distinct streams per base seed


@dataclass(frozen=True)
class RolloutSpec:
    """What to run. `skills` are skill names of the setting or one chain name (a sequential rollout)."""

    setting: str
    skills: tuple[str, ...]
    episodes: int
    objects: tuple[str, ...] | None = None
    num_envs: int = 1
    seed: int = 0
    shard: tuple[int, int] = (0, 1)
    policy: str = "expert"
    checkpoint: str | None = None
    record_cameras: bool = True
    platform: str | None = None
    controller: str = "payload-aware"
    sim_backend: str = "physx_cpu"
    max_steps: int | None = None  # override the env's episode length
    chained: bool = False  # a chain under the spec's chained evaluation protocol (`rollout.chained`)
    # episodes with a plan index below this also record the third-person view and, in a state-only run, the onboard
    # RGB views (videos); the other episodes render nothing
    third_person_episodes: int = 0
    physx_solver: str = field(default_factory=default_physx_solver)  # "pgs" (default) or "tgs" (rows before 2026-11-25)
    rendering: str = DEFAULT_RENDERING  # "rasterized" or "ray-traced" (cameras through SAPIEN's ray tracer; a GPU)
    keep_signals: tuple[str, ...] = ()  # env info signals kept per step in `EpisodeData.signals` (diagnostic benches)
    # the expert of a Pick first turns on the spot to face its object (`expert.look`): what it demonstrates is then
    # visible in the cameras at every step (demonstrations for camera policies); with `labeler` it is the labelling
    # expert that looks first (DAgger on a policy cloned from look-first demonstrations)
    look_first: bool = False
    action_noise: float = 0.0  # DART: executed flight commands get N(0, sigma^2); the recorded action stays clean
    # named evaluation conditions the envs run under (`envs.conditions`; none: today's physics); the starts are the
    # same under every condition (the conditions draw from their own streams)
    condition: tuple[str, ...] = ()
    # DAgger (Ross et al., 2011): `policy` flies, and each frame records this policy's action and phase instead, the
    # correction at the states the flying policy visits ("expert", the one policy that labels states it did not reach)
    labeler: str | None = None
    # a blind control's evaluation: the cameras are not rendered and the policy is given blank (zero) images of
    # their shape instead (a LeRobot policy trained with blanked images; aerobench's `train bc --blind` checkpoints
    # blank their own)
    blind: bool = False
    # also record, each control step, whether the controller's rotor thrusts are clipped (`AerialEnv.flight_statistics`;
    # a side computation that changes no result, so not part of the run's identity; `aerobench eval` turns it on)
    rotor_statistics: bool = False
    realtime: RealtimeSpec | None = None  # the simulation keeps stepping while the policy computes (`rollout.realtime`)
    # the policy acts through LeRobot's PolicyServer (`policies.remote`); where it is served is not part of the run's
    # identity (`as_dict`): a run resumes against a server restarted elsewhere
    policy_server: PolicyServerSpec | None = None
    # episodes that share one scene (layout, object and distractors: a reconfiguration), each with its own start from
    # its own seed (`scene_chunks`): an env that finishes one is reset alone (a partial reset: ManiSkill cannot
    # reconfigure one env of a batch) and runs the next, so a batch of many envs waits for its slowest G episodes, not
    # its slowest one; 1: every episode its own scene (every committed row)
    episodes_per_scene: int = 1

    def __post_init__(self):
        setting = get_setting(self.setting)
        if not self.skills:
            raise ValueError("name at least one skill (or a chain)")
        chains = [s for s in self.skills if s in setting.chains]
        if chains and len(self.skills) > 1:
            raise ValueError(f"a chain ({chains[0]}) runs alone; give either skills or one chain")
        for skill in self.skills:
            if skill not in setting.chains:
                if skill not in SKILLS:
                    valid = ", ".join(list(setting.skills) + list(setting.chains))
                    raise ValueError(f"unknown skill {skill!r}; valid for {setting.name}: {valid}")
                setting.check_skill(skill)
        for obj in self.objects or ():
            setting.check_object(obj)
        if not (isinstance(self.episodes, int) and self.episodes > 0):
            raise ValueError(f"--episodes must be a positive integer, got {self.episodes}")
        last_seed = (2**32 - self.episodes) // SEED_STRIDE  # numpy / SAPIEN seeds are 32-bit
        if not (isinstance(self.seed, int) and 0 <= self.seed <= last_seed):
            raise ValueError(f"--seed must be between 0 and {last_seed} (episode i runs with seed * {SEED_STRIDE} + i, "
                             f"which must fit in 32 bits), got {self.seed}")
        object.__setattr__(self, "physx_solver", check_physx_solver(self.physx_solver))
        object.__setattr__(self, "rendering", check_rendering(self.rendering))
        object.__setattr__(self, "action_noise", check_action_noise(self.action_noise))
        object.__setattr__(self, "condition", parse_condition_names(self.condition))
        conditions = resolve_condition(self.condition)  # they compose: two that set the same model are refused now
        if conditions is not None and conditions.is_visual and not (self.record_cameras or self.blind):
            raise ValueError(f"{', '.join(conditions.names)} change what the cameras see, and this run renders no "
                             f"camera (its policy reads none, or --no-cameras): it would measure nothing")
        if self.rendering != DEFAULT_RENDERING and not self.record_cameras:
            raise ValueError(f"{self.rendering} rendering is for the cameras; drop --no-cameras or the --render option")
        i, k = self.shard
        if not (k >= 1 and 0 <= i < k):
            raise ValueError(f"--shard must be i/k with 0 <= i < k, got {i}/{k}")
        if self.num_envs < 1:
            raise ValueError(f"--num-envs must be at least 1, got {self.num_envs}")
        if self.chained and not chains:
            raise ValueError("the chained protocol runs a chain: give one chain, e.g. --chain pick,transport,place")
        if self.labeler is not None:
            if self.labeler != "expert":
                raise ValueError(f"--label-with takes expert (the privileged expert labels the states another policy "
                                 f"flies to), got {self.labeler!r}")
            if self.policy == self.labeler:
                raise ValueError("--label-with expert labels another policy's flight: give --policy a learned policy "
                                 "and its --checkpoint (e.g. --policy bc --checkpoint RUN/checkpoint)")
            if self.chained:
                raise ValueError("--label-with labels single-skill or chain rollouts, not the chained protocol's")
        if self.look_first and (self.chained or (self.policy != "expert" and self.labeler != "expert")):
            raise ValueError("--look-first changes how the expert flies or labels a Pick: use it with --policy expert "
                             "or with --label-with expert")
        if self.look_first and self.skills != ("pick",):
            raise ValueError(f"--look-first turns to a Pick's object: give --skills pick, not {','.join(self.skills)}")
        if self.blind and self.record_cameras:
            raise ValueError("a blind evaluation renders no camera: it records none")
        if self.sim_backend == "physx_cpu" and self.num_envs != 1:
            raise ValueError("physx_cpu runs one env per process: use --shard i/k to run several processes")
        if self.chained and (self.realtime or self.policy_server):
            raise ValueError("the chained protocol's expert transport is not timed or served remotely: --realtime and "
                             "--policy-server evaluate single skills (drop --chain)")
        if self.policy_server is not None:
            self.policy_server.address_for(self.shard)  # one server per shard
        if not (isinstance(self.episodes_per_scene, int) and self.episodes_per_scene >= 1):
            raise ValueError(f"--episodes-per-scene must be a positive integer, got {self.episodes_per_scene!r}")
        if self.episodes_per_scene > 1 and (self.chained or self.realtime):
            raise ValueError("--episodes-per-scene resets envs alone, which the chained protocol's stage monitor and "
                             "the real-time clock (one per batch) do not follow: use --episodes-per-scene 1 with "
                             "--chain or --realtime")

    @cached_property
    def checkpoints(self) -> dict[str, str | None]:
        """`checkpoint` parsed once: {skill or '*': DIR} (`chained.split_checkpoints`)."""
        return split_checkpoints(self.checkpoint)

    @property
    def is_chain(self) -> bool:
        return self.skills[0] in get_setting(self.setting).chains

    def as_dict(self) -> dict:
        return {
            "setting": self.setting, "skills": list(self.skills), "episodes": self.episodes,
            "objects": list(self.objects) if self.objects else None, "seed": self.seed, "policy": self.policy,
            "checkpoint": self.checkpoint, "record_cameras": self.record_cameras, "platform": self.platform,
            "controller": self.controller, "shard": list(self.shard),
            **({"max_steps": self.max_steps} if self.max_steps else {}),  # only when set: older runs stay resumable
            **({"chained": True} if self.chained else {}),
            # named when it is not TGS, the solver of every run before the key existed: those stay resumable (as TGS)
            **({"physx_solver": self.physx_solver} if self.physx_solver != "tgs" else {}),
            **({"rendering": self.rendering} if self.rendering != DEFAULT_RENDERING else {}),
            **({"action_noise": self.action_noise} if self.action_noise else {}),
            **({"look_first": True} if self.look_first else {}),
            **({"condition": list(self.condition)} if self.condition else {}),
            **({"labeler": self.labeler} if self.labeler else {}),
            **({"blind": True} if self.blind else {}),
            **({"realtime": self.realtime.as_dict()} if self.realtime else {}),
            **({"episodes_per_scene": self.episodes_per_scene} if self.episodes_per_scene > 1 else {}),
        }


@dataclass(frozen=True)
class EpisodePlan:
    index: int
    seed: int  # the episode's start: the drone's, the object's and the distractors' poses
    skill: str  # a skill or the chain's name
    object: str | None
    scene_seed: int | None = None  # the seed its scene was built from (None: `seed`; see `scene_chunks`)

    @property
    def scene(self) -> int:
        return self.seed if self.scene_seed is None else self.scene_seed


def blank_cameras(obs: dict, base) -> dict:
    """`obs` with every onboard camera's RGB and depth as zeros of their rendered shape (a blind control's input)."""
    n, out = base.num_envs, {}
    for cam in base.platform.cameras:
        out[cam.uid] = {"rgb": torch.zeros(n, cam.height, cam.width, 3, dtype=torch.uint8),
                        "depth": torch.zeros(n, cam.height, cam.width, 1, dtype=torch.int16)}
    return {**obs, "sensor_data": out}


def plan_episodes(spec: RolloutSpec) -> list[EpisodePlan]:
    """Every episode of the run (all shards): skills round-robin, then objects round-robin (balanced per class)."""
    setting = get_setting(spec.setting)
    objects = spec.objects or (setting.objects if _uses_object(spec) else (None,))
    plans = []
    scenes: dict[tuple[str, str | None], list[int]] = {}  # (skill, object): its episodes' seeds so far
    for i in range(spec.episodes):
        skill = spec.skills[i % len(spec.skills)]
        obj = objects[(i // len(spec.skills)) % len(objects)]
        seed = spec.seed * SEED_STRIDE + i
        group = scenes.setdefault((skill, obj), [])
        scene = group[len(group) - len(group) % spec.episodes_per_scene] if len(group) % spec.episodes_per_scene else seed
        group.append(seed)
        plans.append(EpisodePlan(i, seed, skill, obj, None if scene == seed else scene))
    return plans


def scene_chunks(plans: list[EpisodePlan]) -> list[list[EpisodePlan]]:
    """`plans` grouped by the scene they run in, each group in plan order, the groups in the order of their first
    plan. A scene is its (skill, object)'s `episodes_per_scene` consecutive episodes, built from the first one's seed,
    whatever the shard or the batch size: one env runs a group's episodes one after another (`RolloutRunner`)."""
    chunks: dict[tuple[str, int], list[EpisodePlan]] = {}
    for plan in plans:
        chunks.setdefault((plan.skill, plan.scene), []).append(plan)
    return list(chunks.values())


def check_resets_alone(policy, name: str, num_envs: int) -> None:
    """A one-line ValueError where resetting one env of a batch alone would disturb the others: a policy that keeps one
    action queue for the whole batch (LeRobot's, `resets_whole_batch`) clears every env's queue."""
    if num_envs > 1 and getattr(policy, "resets_whole_batch", False):
        raise ValueError(f"policy {name!r} keeps one action queue for the whole batch, which a reset of one env clears "
                         f"for all: use --episodes-per-scene 1 with --num-envs {num_envs}")


def episode_limit(env: gym.Env) -> int:
    """The env's time limit in control steps (ManiSkill's TimeLimitWrapper holds it; gym's spec may not)."""
    limit = getattr(env, "_max_episode_steps", None) or (env.spec.max_episode_steps if env.spec else None)
    if not limit:
        raise ValueError(f"{env.spec.id if env.spec else env} has no time limit; pass max_episode_steps")
    return int(limit)


def _uses_object(spec: RolloutSpec) -> bool:
    return any(s not in ("nav", "open", "close") for s in spec.skills)


def shard_plans(spec: RolloutSpec) -> list[EpisodePlan]:
    """Shard i of k: the i-th of k contiguous blocks of the plan (balanced too: the plan cycles skills and objects)."""
    i, k = spec.shard
    plans = plan_episodes(spec)
    return plans[i * len(plans) // k : (i + 1) * len(plans) // k]


@dataclass
class Progress:
    """Counts the runner reports after every episode (for a progress bar)."""

    total: int
    done: int = 0
    successes: int = 0
    started: float = field(default_factory=time.monotonic)
    run_done: int = 0  # episodes finished by this process (for the rate)

    @property
    def rate_per_min(self) -> float:
        return 60.0 * self.run_done / max(time.monotonic() - self.started, 1e-9)

    @property
    def eta_s(self) -> float:
        return (self.total - self.done) * 60.0 / self.rate_per_min if self.run_done else math.inf


class RolloutRunner:
    """Runs a spec's episodes into a sink."""

    def __init__(self, spec: RolloutSpec, sink: EpisodeSink, on_episode: Callable[[EpisodeData, Progress], None] | None = None):
        self.spec, self.sink, self.on_episode = spec, sink, on_episode
        self._envs: dict[str, gym.Env] = {}

    def _env(self, skill: str) -> gym.Env:
        if skill not in self._envs:
            spec = self.spec
            kwargs = dict(
                setting=spec.setting, obs_mode="rgbd" if spec.record_cameras else "state_dict",
                num_envs=spec.num_envs, sim_backend=spec.sim_backend, controller=spec.controller,
                physx_solver=spec.physx_solver, rendering=spec.rendering,
            )
            if spec.platform:
                kwargs["platform"] = spec.platform
            if spec.max_steps:
                kwargs["max_episode_steps"] = spec.max_steps
            if spec.condition:
                kwargs["condition"] = spec.condition
            if spec.rotor_statistics:
                kwargs["rotor_statistics"] = True
            if spec.episodes_per_scene > 1:
                kwargs["reconfiguration_freq"] = 0  # the runner reconfigures a batch when it starts new scenes
            if spec.is_chain:
                env_id, kwargs["chain"] = "AeroSequential-v1", skill
            else:
                env_id = SKILL_ENV_IDS[skill]
            freeze_process_heap()  # this process builds env after env: ManiSkill's full collections skip the imports
            self._envs[skill] = gym.make(env_id, **kwargs)
        return self._envs[skill]

    def run(self) -> Progress:
        plans = shard_plans(self.spec)
        done = self.sink.done_indices()
        todo = [p for p in plans if p.index not in done]
        progress = Progress(total=len(plans), done=len(plans) - len(todo))
        n = self.spec.num_envs
        chunks = scene_chunks(todo)  # one episode each unless episodes share scenes
        try:
            for start in range(0, len(chunks), n):
                by_skill: dict[str, list[list[EpisodePlan]]] = {}
                for chunk in chunks[start : start + n]:
                    by_skill.setdefault(chunk[0].skill, []).append(chunk)
                for skill, skill_chunks in by_skill.items():
                    for episode in self._run_wave(skill, skill_chunks):
                        self.sink.write(episode)
                        progress.done += 1
                        progress.run_done += 1
                        progress.successes += episode.record.outcome == "S"
                        if self.on_episode:
                            self.on_episode(episode, progress)
            self.sink.flush()
        finally:
            for env in self._envs.values():
                env.close()
        return progress

    # ------------------------------------------------------------------------------------------------------------------
    def _policy(self, base, checkpoint: str | None):
        """The acting policy: local, or through LeRobot's PolicyServer; under the real-time wrapper when asked."""
        spec = self.spec
        if spec.policy_server is not None:
            from ..policies.remote import RemotePolicy

            policy = RemotePolicy(base, spec.policy_server.address_for(spec.shard), spec.policy, checkpoint,
                                  device=spec.policy_server.device)
        else:
            policy = make_policy(spec.policy, base, checkpoint=checkpoint,
                                 **({"look_first": True} if spec.look_first and not spec.labeler else {}))
        return RealtimePolicy(policy, base, spec.realtime) if spec.realtime is not None else policy

    def _run_wave(self, skill: str, chunks: list[list[EpisodePlan]]) -> Iterator[EpisodeData]:
        """Env row i runs `chunks[i]`'s episodes one after another in the scene of its first plan (its scene seed)
        and yields each episode as a record. The batch reconfigures once; where episodes share scenes, an env whose
        episode ended is reset alone (a partial reset) into its next one and the ended episode is yielded at once;
        otherwise every episode is yielded when the batch ends. Rows past `len(chunks)` pad the batch."""
        env = self._env(skill)
        base = env.unwrapped
        n, device, used = base.num_envs, base.device, len(chunks)
        pad = [chunks[-1]] * (n - used)  # pad rows repeat the last scene
        queues = [list(chunk) for chunk in chunks]
        current: list[EpisodePlan | None] = [queue.pop(0) for queue in queues] + [None] * (n - used)
        seeds = [chunk[0].scene for chunk in chunks + pad]  # each row's episode seed, now its scene's
        options = {"reconfigure": True}
        if chunks[0][0].object is not None:
            options["objects"] = [chunk[0].object for chunk in chunks + pad]
        obs, info = env.reset(seed=seeds if n > 1 else seeds[0], options=options)
        if self.spec.chained:
            policy = ChainedPolicy(base, self.spec.policy, self.spec.checkpoints)
            monitor = ChainMonitor([ev.skill for ev in base.evaluators], n, device=device)
        else:
            checkpoint = checkpoint_for(self.spec.checkpoints, skill)  # one, or one per skill
            policy, monitor = self._policy(base, checkpoint), None
        labeler = (make_policy(self.spec.labeler, base, **({"look_first": True} if self.spec.look_first else {}))
                   if self.spec.labeler else None)
        actors = [actor for actor in (policy, labeler) if actor is not None]
        shares = any(len(chunk) > 1 for chunk in chunks)
        if shares:
            check_resets_alone(policy, self.spec.policy, n)
        for actor in actors:
            actor.reset(torch.arange(n, device=device))
        max_steps = episode_limit(env)
        # the batch's bookkeeping stays on the env's device: a step reads two booleans to the host (whether any env
        # still runs, whether the action is finite) and, where episodes share scenes, a third (whether any ended)
        status = BatchStatus(torch.arange(n, device=device) < used, monitor)
        wave = Wave(base, status, max_steps)
        perturb = ActionNoise(self.spec.action_noise, seeds)

        def begin(rows: list[int], info: dict) -> list[int]:
            """Rows `rows` began the episodes of `seeds`: their start checks and bookkeeping; the rows whose start
            failed (the env's sampler, or the expert's planner with no route from it)."""
            index = torch.tensor(rows, device=device)
            failed = info["init_failed"][index].clone()
            for actor in actors:
                if hasattr(actor, "infeasible"):
                    failed |= actor.infeasible().to(device)[index]
            perturb.restart(rows, [seeds[i] for i in rows])
            return wave.begin(rows, failed)

        def reset_rows(rows: list[int]) -> list[int]:
            """Partial reset: rows `rows` begin the episodes `current` names, in the scenes they have."""
            nonlocal obs
            if not rows:
                return []
            for i in rows:
                seeds[i] = current[i].seed
            index = torch.tensor(rows, device=device)
            obs, info = env.reset(seed=seeds if n > 1 else seeds[0], options={"env_idx": index, "reconfigure": False})
            for actor in actors:
                actor.reset(index)
            return begin(rows, info)

        def turn_over(rows: list[int]) -> Iterator[EpisodeData]:
            """The episodes of `rows` ended (or never started): yield them and start each row's next one."""
            while rows:
                yield from self._ended(rows, current, wave, evaluators, env, policy)
                for i in rows:
                    current[i] = queues[i].pop(0) if queues[i] else None
                rows = reset_rows([i for i in rows if current[i] is not None])  # their starts that failed

        evaluators = [ev.skill for ev in base.evaluators]
        failed = begin(list(range(used)), info)
        resumed = [i for i in range(used) if current[i].seed != seeds[i]]  # a resumed scene's later episode
        if resumed:
            failed = [i for i in failed if i not in resumed] + reset_rows(resumed)
        if shares:
            yield from turn_over(failed)
        third_person = any(p.index < self.spec.third_person_episodes for chunk in chunks for p in chunk)
        for _ in range(max_steps * max(len(chunk) for chunk in chunks)):
            if not status.active.any():
                break
            if self.spec.blind:
                obs = blank_cameras(obs, base)
            action = policy.act(obs)
            if not torch.isfinite(action).all():
                raise ValueError(f"policy {self.spec.policy!r} produced a non-finite action")
            recorded = (action, policy) if labeler is None else (labeler.act(obs), labeler)
            # the policy's own action, or (DAgger) the expert's label: it acts on every step, its phases follow the flight
            wave.frames.append(self._frame(obs, *recorded, base))
            wave.images.append(self._images(obs, base, third_person))
            obs, _, terminated, truncated, info = env.step(perturb(action))
            step = per_env_signals(info, n)
            status.advance(terminated, truncated, step)
            wave.signals.append(step)
            if shares and status.ended.any():
                yield from turn_over(status.ended.nonzero()[:, 0].tolist())
        status.out_of_time()
        yield from self._ended([i for i in range(used) if current[i] is not None], current, wave, evaluators, env,
                               policy)

    def _ended(self, rows: list[int], current: list[EpisodePlan | None], wave: Wave, evaluators: list[str],
               env: gym.Env, policy) -> Iterator[EpisodeData]:
        """The episodes `current` names on `rows`, which have ended: their records (one transfer per buffer key)."""
        if not rows:
            return
        for i, (recorded, shots, trace, steps, truncated, init_failed, task) in zip(rows, wave.episodes(rows)):
            episode = self._episode(current[i], i, recorded, shots, trace, steps, truncated, init_failed, task,
                                    evaluators, wave.base, env.spec.id)
            if isinstance(policy, RealtimePolicy):  # the latency the episode saw: a summary in its record, per step kept
                episode.extra["realtime"] = policy.summary(episode.record.steps)
                episode.signals.update(policy.trace(episode.record.steps))
            yield episode

    def _frame(self, obs, action, policy, base) -> dict[str, torch.Tensor]:
        """What a step records of the acting (or labelling) policy, as `(N, ...)` tensors on the env's device, in the
        dtypes the episode's arrays have (a subclass may record more: `bench/diversity.py`)."""
        phase = (policy.phase() if hasattr(policy, "phase")
                 else torch.full((base.num_envs,), -1, dtype=torch.long, device=base.device))
        return {"state": obs["agent"]["state"].float(), "task_state": base.task_state().float(),
                "action": action.float(), "phase": phase.to(base.device, torch.long)}

    def _images(self, obs, base, third_person: bool) -> dict[str, np.ndarray]:
        """The step's recorded camera frames, on the host."""
        frame = {}
        if self.spec.record_cameras:
            for cam in CAMERAS:
                frame[f"rgb/{cam}"] = obs["sensor_data"][cam]["rgb"].cpu().numpy()
                frame[f"depth/{cam}"] = obs["sensor_data"][cam]["depth"][..., 0].cpu().numpy().clip(0).astype(np.uint16)
        elif third_person:  # a video episode of a state-only run: its onboard views are rendered for the video alone
            rendered = base.get_sensor_images()
            for cam in CAMERAS:
                frame[f"rgb/{cam}"] = rendered[cam]["rgb"].cpu().numpy()
        if third_person:  # the env's human-render camera, aimed at the drone at reset (not an observation)
            frame[f"rgb/{THIRD_PERSON}"] = base.render_rgb_array().cpu().numpy()
        return frame

    def _episode(self, plan, row, frames, images, signals, steps, truncated, init_failed, task, evaluators, base,
                 env_id) -> EpisodeData:
        """The episode that env `row` ran: `frames` and `signals` its `(T, ...)` arrays, `images` one dict a step."""
        spec = self.spec
        trace = signals if steps else {}
        segments = ()
        if init_failed or not spec.is_chain:
            outcome = categorize(evaluators[0], trace, truncated, init_failed=init_failed)
        else:  # a chain: the stage that ended the rollout names its mode; S only if every stage succeeded
            segments = tuple(cut_segments(trace, evaluators, truncated, parent_id=f"{spec.setting}/{plan.skill}/{plan.index}"))
            outcome = segments[-1].outcome
        record = EpisodeRecord.from_outcome(
            outcome,
            episode_index=plan.index,
            parent_id=f"{spec.setting}/{plan.skill}/{plan.index}",
            seed=plan.seed,
            shard=spec.shard[0],
            setting=spec.setting,
            skill=plan.skill,
            object=base.target_specs[row].name if base.target is not None else (plan.object or ""),
            platform=base.platform.name,
            policy=spec.policy,
            segments=segments,
        )
        data = {}
        if steps:
            data.update(frames)
            for key in images[0]:
                data[key] = np.stack([frame[key] for frame in images])
            data["events"] = np.stack([trace.get(k, np.zeros(steps)).astype(np.float32) for k in EVENT_FLAGS], -1)
            stage = trace.get("subtask_index", np.zeros(steps)).astype(np.int64)
            # the env reports the stage after the step; the stage acting on step t is the one before it
            acting = np.concatenate([[0], stage[:-1]]) if len(stage) else stage
            data["stage"] = acting
            data["skill"] = np.minimum(acting, len(evaluators) - 1)  # into `skills` (the export maps it onto SKILLS)
        extra = {
            "env_id": env_id,
            "object_mass_kg": float(base.target_mass[row]) if base.target is not None else None,
            "instruction": task,
            "chain": plan.skill if spec.is_chain else None,
            "init_failed": init_failed,
            **({"labeler": spec.labeler} if spec.labeler else {}),
            # where episodes share scenes: the seed its scene (layout, object, distractors) was built from
            **({"scene_seed": plan.scene} if spec.episodes_per_scene > 1 else {}),
        }
        kept = {k: trace[k] for k in spec.keep_signals if k in trace}
        return EpisodeData(record=record, frames=data, task=task, skills=tuple(evaluators), extra=extra, signals=kept)

