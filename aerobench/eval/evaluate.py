"""`aerobench eval`: a policy on a setting's skill x object grid, per-episode records, then the results JSON.

Episodes are the rollout runner's seeded plan with `episodes_per_object` episodes per skill-object pair, so two
policies evaluated with the same seed see the same starts (which makes the paired comparison in `stats` valid).
A learned policy's results also record how many of those starts its training data already had (`provenance.seen_in_training`).
Records are appended as episodes finish; running the same command again continues an interrupted evaluation.
With `workers` > 1 (physx_cpu runs one env per process) the plan is split into that many shards, each run in its own
worker process into its own crash-safe record file (`shards/<i>-of-<k>/records.jsonl`); the results summarize all.
With `ray` the shards are Ray tasks instead (`rollout.ray_shards`: a local runtime or a cluster; `workers` shards,
default one per CPU Ray offers), written to the same files, so `out` must be a folder every worker sees.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..envs.conditions import resolve_condition
from ..envs.control.payload import ControllerMode
from ..envs.tasks import TaskSetting, get_setting
from ..policies.remote import PolicyServerSpec
from ..rollout.chained import checkpoint_for, resolve_chain, split_checkpoints, stage_skills
from ..rollout.episode import CAMERAS, EpisodeData
from ..rollout.realtime import RealtimeSpec
from ..rollout.records import RecordSink, read_records, run_record_files, unique_records
from ..rollout.runner import THIRD_PERSON, Progress, RolloutRunner, RolloutSpec, plan_episodes, shard_plans
from ..threads import torch_threads
from .held_out import seen_in_training, training_starts
from .results import failure_modes, summarize, write_results

RESULTS_FILE = "results.json"


@dataclass(frozen=True)
class EvalConfig:
    policy: str
    setting: str
    skills: tuple[str, ...] = ("pick", "place")
    objects: tuple[str, ...] | None = None
    episodes_per_object: int = 50
    checkpoint: str | None = None
    num_envs: int = 1
    episodes_per_scene: int = 1  # episodes that share a scene, an env reset alone between them (`RolloutSpec`)
    seed: int = 0
    video: int = 0  # rollout videos of the first N episodes
    sim_backend: str = "physx_cpu"
    label: str | None = None  # the leaderboard row name (e.g. with the training budget)
    dataset_revision: str | None = None
    max_steps: int | None = None  # truncate every episode after this many control steps (smoke tests)
    chain: tuple[str, ...] | None = None  # e.g. ("pick", "transport", "place"): the spec's chained protocol
    workers: int = 1  # shards run in this many worker processes (with `ray`: this many Ray tasks; 1 = one per CPU)
    ray: str | None = None  # run the shards on Ray: "local" (this machine's cores), "auto" or a head's HOST:PORT
    inputs: str | None = None  # the input tier the evaluation is for (`aerobench.tiers`): a policy outside it is refused
    blind: bool = False  # a blind control: blank cameras instead of rendered ones (`RolloutSpec.blind`)
    condition: tuple[str, ...] = ()  # named evaluation conditions (`envs.conditions`), on the same starts as nominal
    realtime: RealtimeSpec | None = None  # real-time evaluation (`rollout.realtime`)
    policy_server: PolicyServerSpec | None = None  # act through LeRobot's PolicyServer (`policies.remote`)
    controller: str = "payload-aware"  # the flight controller (spec: payload-aware; nominal: no payload estimate)

    def __post_init__(self):
        ControllerMode.parse(self.controller)  # an unknown controller is one line here, not in a worker
        if not (isinstance(self.workers, int) and self.workers >= 1):
            raise ValueError(f"--workers must be a positive integer, got {self.workers}")
        if self.workers > 1 and self.num_envs > 1:
            raise ValueError("--workers splits physx_cpu runs (one env each) into processes; with --num-envs use one")
        if self.policy_server is not None:
            if self.ray is not None:
                raise ValueError("--policy-server runs with --workers (one server per worker), not --ray")
            if len(self.policy_server.addresses) != self.workers:
                raise ValueError(f"--policy-server: LeRobot's PolicyServer serves one client at a time, so give one "
                                 f"server per worker ({self.workers} workers, {len(self.policy_server.addresses)} "
                                 f"servers)")

    def resolve(self) -> ResolvedEval:
        """Everything an evaluation reads, looked up and checked once (see `ResolvedEval`). Raises a ValueError for an
        unknown policy or setting, a bad checkpoint, a policy outside `inputs`, or a per-skill mapping without a
        folder for a skill the policy acts."""
        from ..policies import policy_needs_images
        from ..policies.registry import check_policy_tier, policy_input_tier

        checkpoints = split_checkpoints(self.checkpoint)
        paths = list(checkpoints.values())
        # the policy reads rendered cameras if any stage checkpoint does (a blind control reads none); this also
        # validates name and checkpoints before any other work
        reads_images = any(policy_needs_images(self.policy, c) for c in paths)
        if self.inputs is not None:
            check_policy_tier(self.policy, paths, self.inputs)
        if self.policy_server is not None:  # what LeRobot's server cannot serve is refused before any connection
            from ..policies.remote import served_config

            for path in paths:
                served_config(self.policy, path)
        tier = policy_input_tier(self.policy, paths)  # the widest of the stage checkpoints' tiers
        setting = get_setting(self.setting)
        chain = resolve_chain(setting, self.chain) if self.chain else None
        skills = (chain,) if chain else tuple(self.skills)
        acted = [s for s in stage_skills(self.chain) if s != "nav"] if self.chain else skills
        for skill in acted if self.policy not in ("expert", "random") else ():
            checkpoint_for(checkpoints, skill)  # a per-skill mapping names every skill the policy acts
        uses_objects = any(s not in ("nav", "open", "close") for s in skills)
        n_objects = len(self.objects or setting.objects) if uses_objects else 1
        if not (isinstance(self.episodes_per_object, int) and self.episodes_per_object > 0):
            raise ValueError(f"--episodes-per-object must be a positive integer, got {self.episodes_per_object}")
        spec = RolloutSpec(
            setting=self.setting, skills=skills, objects=tuple(self.objects) if self.objects else None,
            episodes=self.episodes_per_object * n_objects * len(skills), num_envs=self.num_envs, seed=self.seed,
            policy=self.policy, checkpoint=self.checkpoint, record_cameras=reads_images and not self.blind,
            sim_backend=self.sim_backend, max_steps=self.max_steps, chained=bool(self.chain),
            third_person_episodes=self.video, blind=self.blind, condition=self.condition, realtime=self.realtime,
            policy_server=self.policy_server, controller=self.controller, rotor_statistics=True,
            episodes_per_scene=self.episodes_per_scene,
        )
        return ResolvedEval(config=self, setting=setting, chain=chain, checkpoints=checkpoints, input_tier=tier,
                            spec=spec)


@dataclass(frozen=True)
class ResolvedEval:
    """An evaluation's inputs, resolved once from its `EvalConfig`: the runner, the held-out check, the chain and the
    results read these instead of looking the setting up or parsing the checkpoint string again.

    Not sent to worker processes (the setting holds mappings pickle refuses): a worker resolves its config once.
    """

    config: EvalConfig
    setting: TaskSetting
    chain: str | None  # the setting's chain the stages name (`--chain pick,transport,place`), or None
    checkpoints: dict[str, str | None]  # {skill or '*': DIR}: `--checkpoint DIR` or `pick=DIR,place=DIR`
    input_tier: str  # the policy's input tier (`aerobench.tiers`)
    spec: RolloutSpec  # every shard's episodes; `shard_spec` gives one shard's

    @property
    def policy(self) -> str:
        return self.config.policy

    @property
    def record_cameras(self) -> bool:
        """Whether the cameras are rendered for the policy (not for a state-only policy, nor a blind control)."""
        return self.spec.record_cameras

    def shard_spec(self, shard: tuple[int, int]) -> RolloutSpec:
        return replace(self.spec, shard=shard)


def evaluate(
    config: EvalConfig,
    out: str | Path,
    on_episode: Callable[[EpisodeData, Progress], None] | None = None,
    command: str | None = None,
    on_progress: Callable[[int, int, float], None] | None = None,
) -> dict:
    """Run (or continue) the evaluation into `out/records.jsonl` (with workers: one file per shard) and write
    `out/results.json`; returns the results. With `config.ray`, `on_progress(done, successes, seconds)` hears of
    the episodes of every shard as they finish."""
    out = Path(out)
    plan = config.resolve()
    spec = plan.spec
    held_out = held_out_check(plan)
    if config.policy_server is not None:
        from ..policies.remote import probe

        probe(config.policy_server)  # a server that is down is one line before any env starts
    if config.ray is not None:
        _run_on_ray(config, out, on_progress)
    elif config.workers == 1:
        run_shard(plan, out, (0, 1), on_episode)
    else:
        _run_in_workers(plan, out, on_episode)
    record_files = run_record_files(out, _run_spec(config, spec))  # every shard file, whatever layout wrote it
    provenance = {
        "policy": config.policy, "checkpoint": _resolved(plan.checkpoints),
        "dataset_revision": config.dataset_revision, "seed": config.seed, "skills": list(spec.skills),
        "chain": list(config.chain) if config.chain else None,
        "objects": list(config.objects) if config.objects else None, "episodes_per_object": config.episodes_per_object,
        "sim_backend": config.sim_backend, "physx_solver": spec.physx_solver, "num_envs": config.num_envs,
        "max_steps": config.max_steps,
        "records": ",".join(str(f.relative_to(out)) for f in record_files),
        "command": command, "seen_in_training": held_out,
        **({"blind": True} if config.blind else {}),
        **({"controller": config.controller} if config.controller != ControllerMode.PAYLOAD_AWARE else {}),
        **({"conditions": resolve_condition(spec.condition).records()} if spec.condition else {}),
        **({"realtime": config.realtime.as_dict()} if config.realtime else {}),
        **({"policy_server": list(config.policy_server.addresses)} if config.policy_server else {}),
        **({"episodes_per_scene": config.episodes_per_scene} if config.episodes_per_scene > 1 else {}),
    }
    rows = unique_records(record_files)
    results = summarize(rows, provenance, label=config.label, inputs=plan.input_tier)
    videos = sorted(out.glob("**/videos/*.mp4"))
    if videos:
        results["videos"] = [str(p.relative_to(out)) for p in videos]
    write_results(out / RESULTS_FILE, results)
    return results


def run_shard(
    plan: ResolvedEval, folder: Path, shard: tuple[int, int],
    on_episode: Callable[[EpisodeData, Progress], None] | None = None,
) -> Path:
    """One shard's episodes into `folder/records.jsonl` (continuing what is there); returns that file."""
    spec = plan.shard_spec(shard)
    run = _run_spec(plan.config, spec)
    root = folder.parent.parent if folder.parent.name == "shards" else folder
    # an episode another shard file of this run holds (e.g. written under an earlier shard layout) is not run again
    elsewhere = {int(r["episode_index"]) for f in run_record_files(root, run)
                 if f.parent != folder for r in read_records(f)}
    sink = RecordSink(folder, run, recorded_elsewhere=elsewhere)
    videos = folder / "videos"

    def after(episode: EpisodeData, progress: Progress) -> None:
        if episode.record.episode_index < plan.config.video and "rgb/drone_front" in episode.frames:
            write_episode_video(episode, videos / f"episode_{episode.record.episode_index:06d}.mp4")
        if on_episode:
            on_episode(episode, progress)

    RolloutRunner(spec, sink, on_episode=after).run()
    return sink.path


def _run_spec(config: EvalConfig, spec: RolloutSpec) -> dict:
    """What a shard folder's run.json holds: the rollout spec and the per-object count."""
    return {**spec.as_dict(), "episodes_per_object": config.episodes_per_object}


def _run_shard_in_worker(config: EvalConfig, folder: Path, shard: tuple[int, int]) -> Path:
    with torch_threads():  # one process per core: more threads than cores slow small torch ops many-fold
        return run_shard(config.resolve(), folder, shard)


def exit_with_parent(parent_pid: int, poll_s: float = 1.0) -> None:
    """Worker-process initializer: quiets the libraries as the CLI does, and a daemon thread ends the worker once the
    process that started it is gone. A driver killed mid-run (Ctrl-C twice, `kill`) otherwise leaves its workers
    running their shards to the end, still appending episodes to the shard files that a re-run of the same command
    is resuming."""
    import os
    import threading
    import time

    from ..quiet import quiet_libraries

    quiet_libraries()  # a spawned worker starts with the libraries' defaults

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        os._exit(1)

    threading.Thread(target=watch, daemon=True, name="exit-with-parent").start()


WORKER_POLL_S = 2.0  # how often the driver counts the workers' finished episodes for its progress bar


def _run_in_workers(plan: ResolvedEval, out: Path, on_episode) -> list[Path]:
    """Every shard in a worker process (spawned: SAPIEN and torch state is not fork-safe); `on_episode(None,
    progress)` hears of the episodes every shard has finished, counted from their record files while they run."""
    import multiprocessing
    import os
    from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor, wait

    config, spec = plan.config, plan.spec
    k = config.workers
    out.mkdir(parents=True, exist_ok=True)
    folders = [out / "shards" / f"{i}-of-{k}" for i in range(k)]
    # a worker starts cold (its imports and env: 10-15 s on a 2-core machine): none for a shard with nothing left
    recorded = {int(r["episode_index"]) for f in run_record_files(out, _run_spec(config, spec)) for r in read_records(f)}
    pending = [i for i in range(k)
               if any(episode.index not in recorded for episode in shard_plans(plan.shard_spec((i, k))))]
    if pending:
        progress = Progress(total=spec.episodes, done=len(recorded))
        with ProcessPoolExecutor(len(pending), mp_context=multiprocessing.get_context("spawn"),
                                 initializer=exit_with_parent, initargs=(os.getpid(),)) as pool:
            futures = {pool.submit(_run_shard_in_worker, config, folders[i], (i, k)): i for i in pending}
            while futures:
                done, _ = wait(futures, timeout=WORKER_POLL_S, return_when=FIRST_EXCEPTION)
                for future in done:
                    future.result()  # a worker's error (e.g. a bad checkpoint) surfaces here
                    futures.pop(future)
                if on_episode is not None:
                    rows = [r for f in folders for r in (read_records(f / "records.jsonl")
                                                         if (f / "records.jsonl").is_file() else [])]
                    new = [r for r in rows if int(r["episode_index"]) not in recorded]
                    if len(new) != progress.run_done or not futures:
                        progress.done, progress.run_done = len(recorded) + len(new), len(new)
                        progress.successes = sum(r["outcome"] == "S" for r in new)
                        on_episode(None, progress)
    return [folder / "records.jsonl" for folder in folders]


def _shard_task(config: EvalConfig, folder: str, shard: tuple[int, int], progress_actor) -> str:
    """One Ray task: one shard's episodes into `folder/records.jsonl`."""
    from ..rollout.ray_shards import episode_reporter

    with torch_threads():
        return str(run_shard(config.resolve(), Path(folder), shard, on_episode=episode_reporter(progress_actor)))


def _run_on_ray(config: EvalConfig, out: Path, on_progress) -> list[Path]:
    from ..rollout.ray_shards import connect, default_shards, run_shards, shard_gpus

    connect(config.ray)
    k = config.workers if config.workers > 1 else default_shards(config.sim_backend)
    out.mkdir(parents=True, exist_ok=True)
    folders = [out / "shards" / f"{i}-of-{k}" for i in range(k)]
    files = run_shards(_shard_task, [(config, str(f), (i, k)) for i, f in enumerate(folders)], on_progress=on_progress,
                       num_gpus=shard_gpus(config.sim_backend))
    return [Path(f) for f in files]


def held_out_check(plan: ResolvedEval) -> dict | None:
    """How many planned episodes start where the checkpoint's training data started (None for expert / random).
    Warns on stderr: evaluating with the seed the demonstrations were generated with replays their starts."""
    if plan.policy in ("expert", "random"):
        return None
    starts = training_starts(plan.policy, plan.checkpoints)
    plans = plan_episodes(plan.spec)
    seen = seen_in_training(plan.setting, plans, starts)
    if seen:
        print(f"warning: {len(seen)} of {len(plans)} evaluation episodes start where the policy's training episodes "
              f"did ({', '.join(starts.sources)}); pass a --seed the training data was not generated with for "
              f"held-out starts", file=sys.stderr)
    if starts.untraced:
        print(f"warning: could not find what {', '.join(starts.untraced)} trained on, so held-out starts are not "
              f"checked", file=sys.stderr)
    return {"episodes": len(seen), "of": len(plans), "sources": starts.sources, "untraced": starts.untraced}


def _resolved(checkpoints: dict[str, str | None]) -> str | None:
    """The checkpoint's path (each path of a per-skill `pick=A,place=B` mapping): relative to the working directory
    when it lies inside it (e.g. `leaderboards/checkpoints/...` from the repository root, so a committed results file
    names a checkpoint any clone has), else absolute."""
    if "*" in checkpoints:
        return _portable(checkpoints["*"]) if checkpoints["*"] else None
    return ",".join(f"{skill}={_portable(p)}" for skill, p in checkpoints.items())


def _portable(path: str) -> str:
    resolved, here = Path(path).resolve(), Path.cwd().resolve()
    return str(resolved.relative_to(here)) if resolved.is_relative_to(here) else str(resolved)


def write_episode_video(episode: EpisodeData, path: Path, fps: int = 20) -> None:
    """The third-person view above the three onboard RGB cameras side by side (the onboard strip alone when the
    episode has no third-person frames)."""
    from ..video import write_video

    frames = np.concatenate([episode.frames[f"rgb/{cam}"] for cam in CAMERAS], axis=2)
    third = episode.frames.get(f"rgb/{THIRD_PERSON}")
    if third is not None:  # scale the strip to the view's width (nearest neighbour: whole-pixel factor)
        factor = max(1, third.shape[2] // frames.shape[2])
        strip = frames.repeat(factor, axis=1).repeat(factor, axis=2)[:, :, : third.shape[2]]
        width = min(strip.shape[2], third.shape[2])
        frames = np.concatenate([third[:, :, :width], strip[:, :, :width]], axis=1)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_video(list(frames), path, fps=fps)


def format_table(results: dict) -> str:
    """Plain-text per skill x object table with SE, Wilson interval, n and the leading failure mode."""
    lines = [f"{results['label']} on {results['setting']}: Mean S.R. {100 * results['mean_sr']:.1f}% "
             f"({results['episodes']} episodes)"]
    header = f"{'skill':<8} {'object':<17} {'success %':>13} {'wilson95 %':>13} {'n':>4}  leading failure mode"
    lines.append(header)
    for c in results["cells"]:
        failures = failure_modes(c["modes"])
        leading = max(failures, key=failures.get) if failures else "-"
        lo, hi = c["wilson95"]
        lines.append(f"{c['skill']:<8} {c['object'] or '-':<17} {100 * c['success_rate']:>6.1f} ± {100 * c['se']:<4.1f} "
                     f"{100 * lo:>5.1f}-{100 * hi:<6.1f} {c['n']:>4}  {leading}"
                     + (f" ({failures[leading]})" if failures else ""))
    for name, stages in results.get("chains", {}).items():
        parts = [f"{s['skill']} {s['successes']}/{s['reached']}" for s in stages]
        lines.append(f"chain {name}: " + " -> ".join(parts))
    return "\n".join(lines)
