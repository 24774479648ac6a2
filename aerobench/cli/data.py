"""`aerobench generate` and `aerobench dataset`: demonstrations into a LeRobotDataset, and tools on one."""

from __future__ import annotations

from pathlib import Path

from ..progress import progress_bar, ray_progress_bar
from .common import Parser, UserError, add_ray_options, parse_csv, parse_shard
from .evaluation import add_condition_option, add_scene_sharing_option


def add_generate(sub) -> None:
    p = sub.add_parser("generate", help="generate annotated demonstrations and export them as a LeRobotDataset v3")
    p.add_argument("--setting", required=True, help="TidyHouse, PrepareGroceries, PackageDelivery, LongHorizonRearrangement")
    p.add_argument("--skills", type=parse_csv, required=True, help="comma-separated skills (pick,place,...) or one chain")
    p.add_argument("--episodes", type=int, required=True)
    p.add_argument("--objects", type=parse_csv, default=None, help="comma-separated objects (default: all of the setting's)")
    p.add_argument("--num-envs", type=int, default=1, help="parallel envs (physx_cuda only; CPU: use --shard)")
    add_scene_sharing_option(p)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--shard", type=parse_shard, default=(0, 1), help="i/k: this process runs the i-th of k contiguous blocks of the episodes")
    p.add_argument("--keep", choices=("success", "all"), default="success", help="which episodes enter the dataset")
    p.add_argument("--language", action="store_true",
                   help="also write the phases and stages as LeRobot language_persistent subtask rows (kept by "
                        "lerobot-edit-dataset; LeRobot 0.6.1's lerobot-dataset-viz cannot read such datasets)")
    p.add_argument("--policy", default="expert", help="the policy that flies: expert (default), random, or a "
                                                      "learned one (bc, ppo, ...) with --checkpoint")
    p.add_argument("--checkpoint", default=None, help="checkpoint of a learned --policy (e.g. RUN/checkpoint)")
    p.add_argument("--label-with", default=None, choices=("expert",),
                   help="DAgger: the --policy flies and the dataset records the expert's action at each state it "
                        "visits (keep every outcome: --keep all; docs/datasets.md)")
    p.add_argument("--platform", default=None, help="gripper or arm (default: the skill's)")
    p.add_argument("--controller", default="payload-aware", help="payload-aware or nominal")
    p.add_argument("--no-cameras", action="store_true", help="state-only episodes (much faster; no image features)")
    p.add_argument("--sim-backend", default="physx_cpu", help="physx_cpu or physx_cuda")
    p.add_argument("--render", default="rasterized", choices=("rasterized", "ray-traced"),
                   help="how the cameras render: SAPIEN's rasterizer, or its ray tracer (needs a ray-tracing GPU)")
    p.add_argument("--action-noise", type=float, default=0.0,
                   help="DART noise: std of Gaussian noise on the executed flight commands (normalised units, e.g. "
                        "0.05); the dataset records the policy's own actions (docs/datasets.md)")
    p.add_argument("--look-first", action="store_true",
                   help="Pick: the expert first turns on the spot until the object is straight ahead, so every move "
                        "it demonstrates is visible in the cameras (data for camera policies; docs/datasets.md); "
                        "with --label-with expert, the labelling expert looks first")
    add_condition_option(p)
    p.add_argument("--part-size", type=int, default=8, help="episodes per crash-safe part")
    p.add_argument("--threads", type=int, default=1, help="torch CPU threads of this process (1: each core runs "
                                                          "its own shard; 1.7x faster than 2 with two shards on two "
                                                          "cores, docs/performance.md)")
    p.add_argument("--out", required=True, help="dataset folder (LeRobotDataset root)")
    add_ray_options(p, "shards")
    p.set_defaults(func=_run_generate)


def _run_generate(args) -> int:
    from ..export.generation import generate, generate_on_ray, open_sink
    from ..rollout.runner import RolloutSpec

    try:
        if args.ray is not None and args.shard != (0, 1):
            raise ValueError("--ray runs every shard itself; leave out --shard")
        spec = RolloutSpec(
            setting=args.setting, skills=args.skills, episodes=args.episodes, objects=args.objects,
            num_envs=args.num_envs, seed=args.seed, shard=args.shard, policy=args.policy, checkpoint=args.checkpoint,
            labeler=args.label_with, platform=args.platform,
            controller=args.controller, record_cameras=not args.no_cameras, sim_backend=args.sim_backend,
            rendering=args.render, action_noise=args.action_noise, condition=args.condition,
            look_first=args.look_first, episodes_per_scene=args.episodes_per_scene,
        )
        if spec.rendering == "ray-traced" and args.ray is None:
            from ..envs.rendering import require_ray_tracing

            require_ray_tracing()  # this machine renders the episodes: say now if it cannot
        from ..envs.control.payload import ControllerMode
        from ..policies.registry import policy_needs_images
        from ..rollout.chained import split_checkpoints

        if args.checkpoint and args.policy in ("expert", "random"):
            raise ValueError(f"the {args.policy} policy takes no --checkpoint")
        # also the early check of a learned policy's checkpoint, before any folder is written
        if any(policy_needs_images(args.policy, c) for c in split_checkpoints(args.checkpoint).values()) and args.no_cameras:
            raise ValueError(f"policy {args.policy} reads the cameras; drop --no-cameras")
        ControllerMode.parse(args.controller)
        if args.platform:
            from ..envs.platforms import get_platform

            get_platform(args.platform)
        if args.threads < 1:
            raise ValueError(f"--threads must be a positive integer, got {args.threads}")
        if args.shards is not None and args.shards < 1:
            raise ValueError(f"--shards must be a positive integer, got {args.shards}")
        if args.ray is None:
            open_sink(spec, args.out, args.keep, args.part_size, args.language)  # a folder of another generation fails before work
        else:
            from ..rollout.ray_shards import connect

            connect(args.ray)  # no cluster at the address: one line before any work
    except ValueError as e:
        raise UserError(str(e)) from None
    bar = progress_bar(spec)
    try:
        if args.ray is not None:
            return _generate_on_ray(args, spec, generate_on_ray)
        progress = generate(spec, args.out, args.keep, args.part_size, on_episode=lambda ep, progress: bar(progress),
                            threads=args.threads, language=args.language)
    except ValueError as e:
        raise UserError(str(e)) from None
    bar(progress, final=True)
    print(f"{progress.done} of {progress.total} episodes in {args.out} (this shard); success {progress.successes} "
          f"of {progress.run_done} run now")
    return 0


def _generate_on_ray(args, spec, generate_on_ray) -> int:
    update, close = ray_progress_bar(spec)
    root = generate_on_ray(spec, args.out, args.keep, args.part_size, address=args.ray, shards=args.shards,
                           on_progress=update, language=args.language)
    close()
    print(f"{spec.episodes} episodes in {args.out}, merged" + ("" if root else " (no episode kept)"))
    return 0


def add_dataset(sub) -> None:
    p = sub.add_parser("dataset", help="inspect, merge, join or filter exported datasets")
    verbs = p.add_subparsers(dest="verb", required=True, parser_class=Parser)
    info = verbs.add_parser("info", help="episode counts by setting, skill, object, outcome and mode")
    info.add_argument("root")
    info.set_defaults(func=_run_dataset_info)
    merge = verbs.add_parser("merge", help="merge the parts (and shards) of a dataset folder into its LeRobot dataset")
    merge.add_argument("root")
    merge.set_defaults(func=_run_dataset_merge)
    join = verbs.add_parser("join", help="one dataset with every episode of several (e.g. demonstrations and their "
                                         "DAgger rounds)")
    join.add_argument("roots", nargs="+", help="merged aerobench dataset folders, in the order their episodes go")
    join.add_argument("--out", required=True, help="the joined dataset's folder (new)")
    join.set_defaults(func=_run_dataset_join)
    filt = verbs.add_parser("filter", help="a new dataset with only the matching episodes")
    filt.add_argument("root")
    filt.add_argument("--out", required=True)
    filt.add_argument("--outcome", type=parse_csv, default=None, help="S, F, T")
    filt.add_argument("--mode", type=parse_csv, default=None)
    filt.add_argument("--skill", type=parse_csv, default=None)
    filt.add_argument("--object", type=parse_csv, default=None)
    filt.set_defaults(func=_run_dataset_filter)


def _dataset_root(text: str) -> Path:
    root = Path(text)
    if not root.is_dir():
        raise UserError(f"no dataset folder at {root}")
    return root


def _run_dataset_info(args) -> int:
    from ..export.info import dataset_info, format_info

    try:
        print(format_info(dataset_info(_dataset_root(args.root))))
    except ValueError as e:
        raise UserError(str(e)) from None
    return 0


def _run_dataset_merge(args) -> int:
    from ..export.tools import merge

    try:
        out = merge(_dataset_root(args.root))
    except ValueError as e:
        raise UserError(str(e)) from None
    print(f"merged into {out}" if out else "no kept episode to merge")
    return 0


def _run_dataset_join(args) -> int:
    from ..export.tools import join_datasets

    try:
        out = join_datasets([_dataset_root(r) for r in args.roots], Path(args.out))
    except ValueError as e:
        raise UserError(str(e)) from None
    print(f"wrote {out}")
    return 0


def _run_dataset_filter(args) -> int:
    from ..export.tools import filter_dataset

    try:
        out = filter_dataset(_dataset_root(args.root), Path(args.out), outcomes=args.outcome, modes=args.mode,
                             skills=args.skill, objects=args.object)
    except ValueError as e:
        raise UserError(str(e)) from None
    print(f"wrote {out}")
    return 0

