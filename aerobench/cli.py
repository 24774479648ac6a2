"""`aerobench` command line: a thin layer that parses arguments and calls the library.

User mistakes (unknown names, bad numbers) end in one line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import sys
from pathlib import Path

from .progress import progress_bar, ray_progress_bar


def _quiet_offline_environment() -> None:
    """Offline by default, nothing waits on a download prompt, and ManiSkill's start-up warnings stay quiet."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
    import logging

    logging.getLogger("mani_skill").setLevel(logging.ERROR)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, no usage dump
        self.exit(2, f"{self.prog}: error: {message}\n")


class UserError(Exception):
    """A mistake in the user's input: reported in one line."""


def _add_fly(sub) -> None:
    from .envs.platforms import PLATFORMS
    from .flight.scenarios import SCENARIOS

    p = sub.add_parser("fly", help="fly one flight-test scenario and print its metrics")
    p.add_argument("--platform", default="gripper", help=f"one of: {', '.join(PLATFORMS)}")
    p.add_argument("--scenario", default="hover", help=f"one of: {', '.join(SCENARIOS)}")
    p.add_argument("--seconds", type=float, default=None, help="flight duration (default: the scenario's)")
    p.add_argument("--payload-kg", type=float, default=None, help="mass held in the gripper (payload default 0.37)")
    p.add_argument("--controller", default="payload-aware", help="payload-aware or nominal")
    p.add_argument("--json", action="store_true", help="print the metrics as one JSON object on the last line")
    p.add_argument("--video", default=None, help="write an MP4 of the flight here")
    p.add_argument("--plot", default=None, help="write a PNG plot (position, tilt, xi_z, rotor thrusts) here")
    p.set_defaults(func=_run_fly)


def _run_fly(args) -> int:
    from .flight.runner import FlightRequest, fly

    try:
        request = FlightRequest(
            platform=args.platform,
            scenario=args.scenario,
            seconds=args.seconds,
            payload_kg=args.payload_kg,
            controller=args.controller,
            video=args.video,
            plot=args.plot,
        )
    except ValueError as e:
        raise UserError(str(e)) from None
    result = fly(request)
    _print_metrics(result.metrics, as_json=args.json)
    return 0


def _add_demo(sub) -> None:
    p = sub.add_parser("demo", help="the gripper platform flies a waypoint square carrying a payload in a room")
    p.add_argument("--out", default="outputs/demo", help="folder for video.mp4, flight.png, metrics.json")
    p.add_argument("--payload-kg", type=float, default=0.37)
    p.add_argument("--no-video", action="store_true", help="skip rendering the videos")
    p.add_argument("--rollout-steps", type=int, default=60, help="length of the random-policy rollout video")
    p.add_argument("--demo-episodes", type=int, default=4, help="expert episodes generated and exported")
    p.add_argument("--eval-episodes-per-object", type=int, default=1, help="episodes per skill-object pair evaluated")
    p.set_defaults(func=_run_demo)


def _run_demo(args) -> int:
    from .flight.runner import FlightRequest, fly

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        request = FlightRequest(
            platform="gripper",
            scenario="square",
            payload_kg=args.payload_kg,
            video=None if args.no_video else str(out / "video.mp4"),
            plot=str(out / "flight.png"),
        )
    except ValueError as e:
        raise UserError(str(e)) from None
    result = fly(request)
    (out / "metrics.json").write_text(json.dumps(result.metrics, indent=2) + "\n")
    _print_metrics(result.metrics, as_json=False)
    written = [p.name for p in (out / "video.mp4", out / "flight.png", out / "metrics.json") if p.exists()]
    written += _demo_world(out, args)
    print(f"wrote {', '.join(written)} to {out}/")
    return 0


DEMO_STARTS = (
    ("AeroPick-v1", {"setting": "TidyHouse"}),
    ("AeroPick-v1", {"setting": "PrepareGroceries"}),
    ("AeroOpen-v1", {"setting": "PrepareGroceries", "fixture": "fridge"}),
    ("AeroSequential-v1", {"setting": "PackageDelivery"}),
    ("AeroSequential-v1", {"setting": "LongHorizonRearrangement"}),
)


def _demo_world(out: Path, args) -> list[str]:
    """Each setting's start as a picture, and a short random-policy rollout as a video."""
    import imageio.v2 as imageio

    from .envs.views import render_env, rollout_frames
    from .flight.runner import write_video

    written = []
    for env_id, kwargs in DEMO_STARTS:
        name = f"start_{kwargs['setting']}_{env_id.removeprefix('Aero').removesuffix('-v1').lower()}.png"
        imageio.imwrite(out / name, render_env(env_id, seed=0, **kwargs))
        written.append(name)
    if not args.no_video:
        frames = rollout_frames("AeroPick-v1", steps=args.rollout_steps, seed=0, setting="TidyHouse")
        write_video(frames, out / "random_rollout.mp4", fps=10)
        frames = rollout_frames("AeroPick-v1", steps=400, seed=0, policy="expert", every=2, setting="TidyHouse")
        write_video(frames, out / "expert_pick.mp4", fps=10)
        written += ["random_rollout.mp4", "expert_pick.mp4"]
    written.append(_demo_dataset(out / "dataset", args.demo_episodes))
    written += _demo_eval(out, args.eval_episodes_per_object)
    return written


def _demo_eval(out: Path, per_object: int) -> list[str]:
    """The expert and the random policy on TidyHouse Pick and Place, per object, and their HTML leaderboard."""
    import shutil

    from .eval.evaluate import RESULTS_FILE, EvalConfig, evaluate, format_table
    from .eval.leaderboard import build_leaderboard

    results = []
    for policy in ("expert", "random"):
        folder = out / "eval" / policy
        if folder.exists():  # the demo always shows a fresh evaluation
            shutil.rmtree(folder)
        print(f"evaluating {policy} on TidyHouse pick, place ({per_object} episode(s) per object) ...", flush=True)
        result = evaluate(EvalConfig(policy=policy, setting="TidyHouse", episodes_per_object=per_object), folder,
                          command=f"aerobench eval --policy {policy} --setting TidyHouse --episodes-per-object {per_object}")
        print(format_table(result))
        results.append(folder / RESULTS_FILE)
    build_leaderboard(results, out / "leaderboard")
    print(f"HTML leaderboard: {(out / 'leaderboard' / 'index.html').resolve()}")
    return ["eval/", "leaderboard/"]


def _demo_dataset(root: Path, episodes: int) -> str:
    """A handful of expert Pick and Place episodes in TidyHouse, exported, with their outcome summary."""
    import shutil

    from .export import DatasetSink
    from .export.tools import dataset_info, format_info
    from .rollout.runner import RolloutRunner, RolloutSpec

    spec = RolloutSpec(setting="TidyHouse", skills=("pick", "place"), episodes=episodes, seed=0)
    if root.exists():  # the demo always shows a fresh dataset
        shutil.rmtree(root)
    sink = DatasetSink(root, {**spec.as_dict(), "keep": "all"}, keep=None, part_size=episodes)
    print(f"generating {episodes} expert episodes (TidyHouse pick, place) into {root} ...", flush=True)
    RolloutRunner(spec, sink, on_episode=lambda ep, p: print(
        f"  episode {ep.record.episode_index}: {ep.record.skill} {ep.record.object}: {ep.record.outcome} ({ep.record.mode}), "
        f"{ep.record.steps} steps", flush=True)).run()
    sink.close()
    print(format_info(dataset_info(root)))
    return "dataset/"


AERO_ENV_IDS = ("AeroPick-v1", "AeroPlace-v1", "AeroNav-v1", "AeroOpen-v1", "AeroClose-v1", "AeroSequential-v1", "AeroFly-v1")


def _add_render(sub) -> None:
    p = sub.add_parser("render", help="picture of an env: the three onboard RGB-D views beside a third-person view")
    p.add_argument("--env", default="AeroPick-v1", help=f"one of: {', '.join(AERO_ENV_IDS)}")
    p.add_argument("--setting", default=None, help="TidyHouse, PrepareGroceries, PackageDelivery, LongHorizonRearrangement")
    p.add_argument("--object", default=None, help="one of the setting's objects (default: sampled)")
    p.add_argument("--platform", default=None, help="gripper or arm (default: the skill's)")
    p.add_argument("--chain", default=None, help="AeroSequential-v1 only: the setting's chain")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True, help="PNG file to write")
    p.set_defaults(func=_run_render)


def _run_render(args) -> int:
    import imageio.v2 as imageio

    from .envs.views import render_env

    if args.env not in AERO_ENV_IDS:
        raise UserError(f"unknown env {args.env!r}; valid envs: {', '.join(AERO_ENV_IDS)}")
    kwargs = {k: v for k, v in (("setting", args.setting), ("object", args.object), ("platform", args.platform), ("chain", args.chain)) if v}
    try:
        picture = render_env(args.env, seed=args.seed, **kwargs)
    except ValueError as e:
        raise UserError(str(e)) from None
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    imageio.imwrite(out, picture)
    print(f"wrote {out} ({picture.shape[1]}x{picture.shape[0]})")
    return 0


def _print_metrics(metrics: dict, as_json: bool) -> None:
    width = max(len(k) for k in metrics)
    for key, value in metrics.items():
        shown = f"{value:.6g}" if isinstance(value, float) else str(value)
        print(f"{key:<{width}}  {shown}")
    if as_json:
        clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in metrics.items()}
        print(json.dumps(clean))


def _shard(text: str) -> tuple[int, int]:
    try:
        i, k = (int(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--shard must look like 0/4, got {text!r}") from None
    return i, k


def _csv(text: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in text.split(",") if v.strip())


def _add_generate(sub) -> None:
    p = sub.add_parser("generate", help="generate annotated demonstrations and export them as a LeRobotDataset v3")
    p.add_argument("--setting", required=True, help="TidyHouse, PrepareGroceries, PackageDelivery, LongHorizonRearrangement")
    p.add_argument("--skills", type=_csv, required=True, help="comma-separated skills (pick,place,...) or one chain")
    p.add_argument("--episodes", type=int, required=True)
    p.add_argument("--objects", type=_csv, default=None, help="comma-separated objects (default: all of the setting's)")
    p.add_argument("--num-envs", type=int, default=1, help="parallel envs (physx_cuda only; CPU: use --shard)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--shard", type=_shard, default=(0, 1), help="i/k: this process runs the i-th of k contiguous blocks of the episodes")
    p.add_argument("--keep", choices=("success", "all"), default="success", help="which episodes enter the dataset")
    p.add_argument("--policy", default="expert", help="expert (default) or random")
    p.add_argument("--platform", default=None, help="gripper or arm (default: the skill's)")
    p.add_argument("--controller", default="payload-aware", help="payload-aware or nominal")
    p.add_argument("--no-cameras", action="store_true", help="state-only episodes (much faster; no image features)")
    p.add_argument("--sim-backend", default="physx_cpu", help="physx_cpu or physx_cuda")
    p.add_argument("--render", default="rasterized", choices=("rasterized", "ray-traced"),
                   help="how the cameras render: SAPIEN's rasterizer, or its ray tracer (needs a ray-tracing GPU)")
    p.add_argument("--part-size", type=int, default=8, help="episodes per crash-safe part")
    p.add_argument("--out", required=True, help="dataset folder (LeRobotDataset root)")
    _add_ray_options(p, "shards")
    p.set_defaults(func=_run_generate)


def _add_ray_options(p, shards_name: str | None = None) -> None:
    p.add_argument("--ray", nargs="?", const="local", default=None, metavar="ADDRESS",
                   help="run the shards as Ray tasks: alone, a local Ray runtime on this machine's cores; with HOST:PORT "
                        "(or auto), the cluster there (ray start --head); the output folder must be shared by the workers")
    if shards_name:
        p.add_argument(f"--{shards_name}", type=int, default=None,
                       help="with --ray: how many shards (default: one per CPU of the Ray runtime)")


def _run_generate(args) -> int:
    from .export.generation import generate, generate_on_ray, open_sink
    from .rollout.runner import RolloutSpec

    try:
        if args.ray is not None and args.shard != (0, 1):
            raise ValueError("--ray runs every shard itself; leave out --shard")
        spec = RolloutSpec(
            setting=args.setting, skills=args.skills, episodes=args.episodes, objects=args.objects,
            num_envs=args.num_envs, seed=args.seed, shard=args.shard, policy=args.policy, platform=args.platform,
            controller=args.controller, record_cameras=not args.no_cameras, sim_backend=args.sim_backend,
            rendering=args.render,
        )
        if spec.rendering == "ray-traced" and args.ray is None:
            from .envs.rendering import require_ray_tracing

            require_ray_tracing()  # this machine renders the episodes: say now if it cannot
        from .envs.control.payload import ControllerMode
        from .policies.registry import POLICIES, make_policy  # noqa: F401

        ControllerMode.parse(args.controller)
        if args.platform:
            from .envs.platforms import get_platform

            get_platform(args.platform)
        if args.shards is not None and args.shards < 1:
            raise ValueError(f"--shards must be a positive integer, got {args.shards}")
        if args.ray is None:
            open_sink(spec, args.out, args.keep, args.part_size)  # a folder of another generation fails before work
        else:
            from .rollout.ray_shards import connect

            connect(args.ray)  # no cluster at the address: one line before any work
    except ValueError as e:
        raise UserError(str(e)) from None
    bar = progress_bar(spec)
    try:
        if args.ray is not None:
            return _generate_on_ray(args, spec, generate_on_ray)
        progress = generate(spec, args.out, args.keep, args.part_size, on_episode=lambda ep, progress: bar(progress))
    except ValueError as e:
        raise UserError(str(e)) from None
    bar(progress, final=True)
    print(f"{progress.done} of {progress.total} episodes in {args.out} (this shard); success {progress.successes} "
          f"of {progress.run_done} run now")
    return 0


def _generate_on_ray(args, spec, generate_on_ray) -> int:
    update, close = ray_progress_bar(spec)
    root = generate_on_ray(spec, args.out, args.keep, args.part_size, address=args.ray, shards=args.shards,
                           on_progress=update)
    close()
    print(f"{spec.episodes} episodes in {args.out}, merged" + ("" if root else " (no episode kept)"))
    return 0


def _add_dataset(sub) -> None:
    p = sub.add_parser("dataset", help="inspect, merge or filter an exported dataset")
    verbs = p.add_subparsers(dest="verb", required=True, parser_class=_Parser)
    info = verbs.add_parser("info", help="episode counts by setting, skill, object, outcome and mode")
    info.add_argument("root")
    info.set_defaults(func=_run_dataset_info)
    merge = verbs.add_parser("merge", help="merge the parts (and shards) of a dataset folder into its LeRobot dataset")
    merge.add_argument("root")
    merge.set_defaults(func=_run_dataset_merge)
    filt = verbs.add_parser("filter", help="a new dataset with only the matching episodes")
    filt.add_argument("root")
    filt.add_argument("--out", required=True)
    filt.add_argument("--outcome", type=_csv, default=None, help="S, F, T")
    filt.add_argument("--mode", type=_csv, default=None)
    filt.add_argument("--skill", type=_csv, default=None)
    filt.add_argument("--object", type=_csv, default=None)
    filt.set_defaults(func=_run_dataset_filter)


def _dataset_root(text: str) -> Path:
    root = Path(text)
    if not root.is_dir():
        raise UserError(f"no dataset folder at {root}")
    return root


def _run_dataset_info(args) -> int:
    from .export.tools import dataset_info, format_info

    try:
        print(format_info(dataset_info(_dataset_root(args.root))))
    except ValueError as e:
        raise UserError(str(e)) from None
    return 0


def _run_dataset_merge(args) -> int:
    from .export.tools import merge

    try:
        out = merge(_dataset_root(args.root))
    except ValueError as e:
        raise UserError(str(e)) from None
    print(f"merged into {out}" if out else "no kept episode to merge")
    return 0


def _run_dataset_filter(args) -> int:
    from .export.tools import filter_dataset

    try:
        out = filter_dataset(_dataset_root(args.root), Path(args.out), outcomes=args.outcome, modes=args.mode,
                             skills=args.skill, objects=args.object)
    except ValueError as e:
        raise UserError(str(e)) from None
    print(f"wrote {out}")
    return 0


def _add_eval(sub) -> None:
    p = sub.add_parser("eval", help="evaluate a policy per skill x object; writes records.jsonl and results.json")
    p.add_argument("--policy", required=True, help="a registered policy: expert, random, bc, ppo, act, diffusion, pi0, pi05")
    p.add_argument("--checkpoint", default=None,
                   help="checkpoint folder of a trained policy, or one per skill: pick=DIR,place=DIR")
    p.add_argument("--setting", required=True, help="TidyHouse, PrepareGroceries, PackageDelivery, LongHorizonRearrangement")
    p.add_argument("--skills", type=_csv, default=("pick", "place"), help="comma-separated skills, or one chain")
    p.add_argument("--chain", type=_csv, default=None,
                   help="chained protocol, e.g. pick,transport,place: the policy acts the skills, the expert transports "
                        "(--checkpoint DIR, or pick=DIR,place=DIR per stage)")
    p.add_argument("--objects", type=_csv, default=None, help="comma-separated objects (default: all of the setting's)")
    p.add_argument("--episodes-per-object", type=int, default=50)
    p.add_argument("--num-envs", type=int, default=1, help="parallel envs (physx_cuda only)")
    p.add_argument("--seed", type=int, default=0, help="seed of the episode plan; for a learned policy, one its "
                   "training data was not generated with (held-out starts; results record any overlap)")
    p.add_argument("--video", type=int, default=0, help="write rollout videos of the first N episodes (renders cameras)")
    p.add_argument("--sim-backend", default="physx_cpu", help="physx_cpu or physx_cuda")
    p.add_argument("--label", default=None, help="leaderboard row name (default: the policy name)")
    p.add_argument("--dataset-revision", default=None, help="the training dataset's revision, kept in the provenance")
    p.add_argument("--max-steps", type=int, default=None,
                   help="truncate episodes after N control steps (smoke tests; not comparable with full-length results)")
    p.add_argument("--workers", type=int, default=1, help="physx_cpu: run the episodes in this many worker processes "
                   "(shards; e.g. the number of cores)")
    p.add_argument("--out", required=True, help="folder for records.jsonl, results.json and videos/")
    _add_ray_options(p)
    p.set_defaults(func=_run_eval)


def _run_eval(args) -> int:
    from .eval.evaluate import EvalConfig, evaluate, format_table

    try:
        config = EvalConfig(
            policy=args.policy, setting=args.setting, skills=args.skills, objects=args.objects,
            episodes_per_object=args.episodes_per_object, checkpoint=args.checkpoint, num_envs=args.num_envs,
            seed=args.seed, video=args.video, sim_backend=args.sim_backend, label=args.label,
            dataset_revision=args.dataset_revision, max_steps=args.max_steps, chain=args.chain, workers=args.workers,
            ray=args.ray,
        )
        if args.max_steps is not None and args.max_steps < 1:
            raise ValueError(f"--max-steps must be a positive integer, got {args.max_steps}")
        config.needs_images()  # unknown names and bad checkpoints fail before any work
        spec = config.rollout_spec(record_cameras=False)
        if args.ray is not None:
            from .rollout.ray_shards import connect

            connect(args.ray)
    except ValueError as e:
        raise UserError(str(e)) from None
    bar = progress_bar(spec)
    ray_update, ray_close = ray_progress_bar(spec) if args.ray is not None else (None, lambda: None)
    try:
        results = evaluate(config, args.out, on_episode=lambda ep, progress: bar(progress),
                           command="aerobench " + shlex.join(sys.argv[1:]), on_progress=ray_update)
    except ValueError as e:
        raise UserError(str(e)) from None
    finally:
        ray_close()
    print(format_table(results))
    print(f"wrote {Path(args.out) / 'results.json'}")
    return 0


def _add_summarize(sub) -> None:
    p = sub.add_parser("summarize", help="a results.json from episode records (of aerobench eval or generate)")
    p.add_argument("records", help="a records.jsonl, or a folder holding one (an eval folder, or a dataset's .aerobench/)")
    p.add_argument("--label", default=None, help="leaderboard row name (default: the policy name)")
    p.add_argument("--out", required=True, help="results file to write")
    p.set_defaults(func=_run_summarize)


def _run_summarize(args) -> int:
    from .eval.evaluate import format_table
    from .eval.results import summarize, write_results
    from .export.card import generate_command
    from .rollout.records import RECORDS_FILE, read_records

    path = Path(args.records)
    for candidate in (path, path / RECORDS_FILE, path / ".aerobench" / RECORDS_FILE):
        if candidate.is_file():
            path = candidate
            break
    else:
        raise UserError(f"no records.jsonl at {args.records} (aerobench eval and generate write one)")
    run_files = [path.parent / "run.json", path.parent / "generation.json"]
    source = next((json.loads(f.read_text()) for f in run_files if f.is_file()), {})
    command = "aerobench " + shlex.join(sys.argv[1:])
    if (path.parent / "generation.json").is_file() and path.parent.name == ".aerobench":
        # Records of a generated dataset: the table's provenance is the generate command, then this one.
        command = f"{generate_command(source, path.parent.parent)} && {command}"
    try:
        results = summarize(read_records(path), {**source, "records": str(path), "command": command}, label=args.label)
    except (ValueError, KeyError) as e:
        raise UserError(f"cannot summarize {path}: {e}") from None
    write_results(args.out, results)
    print(format_table(results))
    print(f"wrote {args.out}")
    return 0


def _add_compare(sub) -> None:
    p = sub.add_parser("compare", help="two evals on the same starts, episode by episode: paired table, exact McNemar "
                       "p-value, 95% interval for the difference, verdict")
    p.add_argument("a", help="eval folder or results file of policy A")
    p.add_argument("b", help="eval folder or results file of policy B (same setting, skills, objects and --seed)")
    p.add_argument("--difference", type=float, default=0.10,
                   help="success-rate difference the power statement is about (default: 0.10, ten points)")
    p.add_argument("--json", default=None, help="also write the comparison to this JSON file")
    p.set_defaults(func=_run_compare)


def _run_compare(args) -> int:
    from .eval.compare import compare, format_comparison

    try:
        result = compare(args.a, args.b, difference=args.difference)
    except ValueError as e:
        raise UserError(str(e)) from None
    print(format_comparison(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return 0


def _add_leaderboard(sub) -> None:
    p = sub.add_parser("leaderboard", help="render Markdown, LaTeX and HTML leaderboards from results files")
    p.add_argument("results", nargs="+", help="results.json files written by aerobench eval")
    p.add_argument("--out", default="leaderboards", help="output folder")
    p.set_defaults(func=_run_leaderboard)


def _run_leaderboard(args) -> int:
    from .eval.leaderboard import build_leaderboard

    try:
        written = build_leaderboard(args.results, args.out)
    except ValueError as e:
        raise UserError(str(e)) from None
    print("wrote " + ", ".join(str(p) for p in written.values()))
    print(f"HTML leaderboard: {Path(args.out) / 'index.html'}")
    return 0


def _add_train(sub) -> None:
    from .train.bc import BCConfig
    from .train.common import add_config_arguments
    from .train.ppo import PPOConfig

    p = sub.add_parser("train", help="train aerobench's own BC or PPO skill policies (checkpoints for --policy bc|ppo)")
    algos = p.add_subparsers(dest="algorithm", required=True, parser_class=_Parser)
    bc = algos.add_parser("bc", help="behaviour cloning on the successful episodes of an exported dataset")
    add_config_arguments(bc, BCConfig, required=("dataset", "out"))
    bc.set_defaults(func=_run_train, config_cls=BCConfig)
    ppo = algos.add_parser("ppo", help="PPO on a skill env, from scratch or from a BC checkpoint (--init-bc DIR)")
    add_config_arguments(ppo, PPOConfig, required=("setting", "skill", "out"))
    ppo.set_defaults(func=_run_train, config_cls=PPOConfig)


def _run_train(args) -> int:
    from .train.common import config_from_args

    try:
        config = config_from_args(args.config_cls, args)
        if args.algorithm == "bc":
            from .train.bc import train_bc as train
        else:
            from .train.ppo import train_ppo as train
        checkpoint = train(config)
    except ValueError as e:
        raise UserError(str(e)) from None
    print(f"checkpoint: {checkpoint}  (aerobench eval --policy {args.algorithm} --checkpoint {checkpoint} ...)")
    return 0


def _add_pi_init(sub) -> None:
    from .policies.pi_init import add_arguments

    p = sub.add_parser("pi-init", help="a pi0/pi0.5 folder for lerobot-train --policy.path: local weights or a tiny random one")
    add_arguments(p)
    p.set_defaults(func=_run_pi_init)


def _run_pi_init(args) -> int:
    from .envs.tasks import snake_name
    from .export.sink import read_dataset_meta
    from .policies.pi_init import PiInitConfig, init_pi

    try:
        out = init_pi(PiInitConfig(policy=args.policy, dataset=args.dataset, out=args.out, variant=args.variant,
                                   weights=args.weights, tokenizer=args.tokenizer, seed=args.seed))
    except ValueError as e:
        raise UserError(str(e)) from None
    meta = read_dataset_meta(Path(args.dataset)) or {}
    setting = meta.get("generation", {}).get("setting", "TidyHouse")
    config = f"configs/{args.policy}_{snake_name(setting)}.json"
    print(f"wrote {out}  (lerobot-train --config_path {config} --policy.path {out} --dataset.root {args.dataset} ...)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="aerobench", description="aerobench: aerial manipulation benchmark (see README.md)")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_fly(sub)
    _add_demo(sub)
    _add_render(sub)
    _add_generate(sub)
    _add_dataset(sub)
    _add_eval(sub)
    _add_train(sub)
    _add_pi_init(sub)
    _add_summarize(sub)
    _add_compare(sub)
    _add_leaderboard(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _quiet_offline_environment()
    try:
        return args.func(args)
    except UserError as e:
        print(f"aerobench {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"aerobench {args.command}: interrupted; run the same command again to continue", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
