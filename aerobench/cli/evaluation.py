"""`aerobench eval`, `conditions`, `summarize`, `compare`, `plan` and `leaderboard`: scoring policies and presenting the
scores."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

from ..progress import progress_bar, ray_progress_bar
from .common import UserError, add_ray_options, parse_csv


def add_eval(sub) -> None:
    p = sub.add_parser("eval", help="evaluate a policy per skill x object; writes records.jsonl and results.json")
    p.add_argument("--policy", default=None, help="a registered policy: expert, random, bc, ppo, perceive_act, act, diffusion, pi0, pi05 "
                   "(required unless --policy-server gives --policy-type)")
    p.add_argument("--checkpoint", default=None,
                   help="checkpoint folder of a trained policy, or one per skill: pick=DIR,place=DIR")
    p.add_argument("--setting", required=True, help="TidyHouse, PrepareGroceries, PackageDelivery, LongHorizonRearrangement")
    p.add_argument("--skills", type=parse_csv, default=("pick", "place"), help="comma-separated skills, or one chain")
    p.add_argument("--chain", type=parse_csv, default=None,
                   help="chained protocol, e.g. pick,transport,place: the policy acts the skills, the expert transports "
                        "(--checkpoint DIR, or pick=DIR,place=DIR per stage)")
    p.add_argument("--objects", type=parse_csv, default=None, help="comma-separated objects (default: all of the setting's)")
    p.add_argument("--episodes-per-object", type=int, default=50)
    p.add_argument("--num-envs", type=int, default=1, help="parallel envs (physx_cuda only)")
    add_scene_sharing_option(p)
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
    p.add_argument("--inputs", default=None, choices=("vision", "privileged"),
                   help="the input tier this evaluation is for (aerobench.tiers): a policy that reads outside it is "
                        "refused (results always record the policy's tier)")
    p.add_argument("--blind", action="store_true",
                   help="a blind control: the policy gets blank cameras (for a LeRobot policy trained with blanked "
                        "images; docs/training.md); nothing is rendered")
    add_condition_option(p)
    p.add_argument("--controller", default="payload-aware", choices=("payload-aware", "nominal"),
                   help="the flight controller: payload-aware (the spec's; estimates a carried mass) or nominal (feeds "
                        "the airframe's mass forward; the control arm for the payload conditions)")
    p.add_argument("--out", required=True, help="folder for records.jsonl, results.json and videos/")
    add_ray_options(p)
    add_realtime_options(p)
    p.set_defaults(func=_run_eval)


def add_scene_sharing_option(p) -> None:
    """`--episodes-per-scene G` (eval and generate): partial resets within a batch (`RolloutSpec.episodes_per_scene`)."""
    p.add_argument("--episodes-per-scene", type=int, default=1, metavar="G",
                   help="episodes that share one scene (layout, object, distractors), each from its own start: an env that finishes one is reset alone into the next, so a physx_cuda batch is not held up by its slowest episode (docs/gpu.md); 1: every episode its own scene, as the leaderboard rows")


def add_condition_option(p) -> None:
    """`--condition NAME[,NAME]` (eval and generate): named evaluation conditions (`aerobench conditions`)."""
    p.add_argument("--condition", type=parse_csv, default=(), metavar="NAME[,NAME]",
                   help="run under named evaluation conditions (wind, surface effects, motor lag, sensor noise, "
                        "payload mismatch; for camera policies lighting, surface colours, camera noise and motion "
                        "blur; `aerobench conditions` lists them) on the same starts as without")


def add_conditions(sub) -> None:
    p = sub.add_parser("conditions", help="list the named evaluation conditions: name, version, parameters, source")
    p.set_defaults(func=_run_conditions)


def _run_conditions(args) -> int:
    from ..envs.conditions import describe_conditions

    print("\n".join(describe_conditions()))
    return 0


def add_realtime_options(p) -> None:
    """Real-time evaluation and LeRobot's remote inference (docs/robustness.md, "Real-time evaluation")."""
    p.add_argument("--realtime", action="store_true",
                   help="the simulation keeps stepping while the policy computes: an answer applies ceil(L / 50 ms) "
                        "control steps after its observation (L: --inference-latency-ms, else each request's own time)")
    p.add_argument("--inference-latency-ms", type=float, default=None,
                   help="with --realtime: a fixed inference latency in ms (default: the policy's own, measured)")
    p.add_argument("--hold", default="last", choices=("last", "hover"),
                   help="with --realtime: the command while the policy computes: the last one, or hover (zero "
                        "velocity and yaw rate, gripper and arm as last commanded)")
    p.add_argument("--schedule", default="sync", choices=("sync", "async"),
                   help="with --realtime: ask the policy when its actions ran out (sync, LeRobot's select_action), or "
                        "early enough that its next answer arrives as they run out (async, LeRobot's async inference)")
    p.add_argument("--policy-server", type=parse_csv, default=None, metavar="HOST:PORT[,HOST:PORT...]",
                   help="act through LeRobot's PolicyServer (python -m lerobot.async_inference.policy_server) there; "
                        "one server per --workers worker")
    p.add_argument("--policy-type", default=None,
                   help="with --policy-server: the checkpoint's LeRobot policy (act, diffusion, pi0, pi05)")
    p.add_argument("--policy-device", default="cpu", help="with --policy-server: the device the server runs it on")
    p.add_argument("--trust-policy-server", action="store_true",
                   help="allow a --policy-server that is not on this machine: LeRobot's transport unpickles what "
                        "the server sends, which can run code here, so only for a server you trust")


def realtime_settings(args):
    """(policy name, RealtimeSpec or None, PolicyServerSpec or None) from the eval options; ValueError if they
    contradict each other."""
    from ..policies.remote import PolicyServerSpec
    from ..rollout.realtime import RealtimeSpec

    timed = args.inference_latency_ms is not None or args.hold != "last" or args.schedule != "sync"
    if timed and not args.realtime:
        raise ValueError("--inference-latency-ms, --hold and --schedule set up --realtime: add --realtime")
    realtime = RealtimeSpec(args.inference_latency_ms, args.hold, args.schedule) if args.realtime else None
    policy = args.policy
    if args.policy_server is None:
        if args.policy_type or args.trust_policy_server or args.policy_device != "cpu":
            raise ValueError("--policy-type, --policy-device and --trust-policy-server go with --policy-server")
        if policy is None:
            raise ValueError("give --policy (or --policy-server with --policy-type)")
        return policy, realtime, None
    if args.policy_type is None and policy is None:
        raise ValueError("--policy-server needs --policy-type (act, diffusion, pi0, pi05)")
    if args.policy_type and policy and args.policy_type != policy:
        raise ValueError(f"--policy {policy} and --policy-type {args.policy_type} disagree; give one")
    server = PolicyServerSpec(tuple(args.policy_server), trust=args.trust_policy_server, device=args.policy_device)
    return args.policy_type or policy, realtime, server


def _run_eval(args) -> int:
    from ..eval.evaluate import EvalConfig, evaluate, format_table

    try:
        policy, realtime, server = realtime_settings(args)
        config = EvalConfig(
            policy=policy, setting=args.setting, skills=args.skills, objects=args.objects,
            episodes_per_object=args.episodes_per_object, checkpoint=args.checkpoint, num_envs=args.num_envs,
            seed=args.seed, video=args.video, sim_backend=args.sim_backend, label=args.label,
            dataset_revision=args.dataset_revision, max_steps=args.max_steps, chain=args.chain, workers=args.workers,
            ray=args.ray, inputs=args.inputs, blind=args.blind, realtime=realtime, policy_server=server,
            condition=args.condition, controller=args.controller, episodes_per_scene=args.episodes_per_scene,
        )
        if args.max_steps is not None and args.max_steps < 1:
            raise ValueError(f"--max-steps must be a positive integer, got {args.max_steps}")
        spec = config.resolve().spec  # bad names, checkpoints, or a policy outside --inputs fail before any work
        if args.ray is not None:
            from ..rollout.ray_shards import connect

            connect(args.ray)
    except ValueError as e:
        raise UserError(str(e)) from None
    bar = progress_bar(spec)
    ray_update, ray_close = ray_progress_bar(spec) if args.ray is not None else (None, lambda: None)
    last = {}

    def on_episode(episode, progress):
        last["progress"] = progress
        bar(progress)

    try:
        results = evaluate(config, args.out, on_episode=on_episode, command="aerobench " + shlex.join(sys.argv[1:]),
                           on_progress=ray_update)
    except (ValueError, ConnectionError) as e:  # ConnectionError: a policy server down or answering garbage
        raise UserError(str(e)) from None
    finally:
        ray_close()
        if "progress" in last:
            bar(last["progress"], final=True)  # the bar's line ends before the table
    print(format_table(results))
    print(f"wrote {Path(args.out) / 'results.json'}")
    return 0


def add_summarize(sub) -> None:
    p = sub.add_parser("summarize", help="a results.json from episode records (of aerobench eval or generate)")
    p.add_argument("records", help="a records.jsonl, or a folder holding one (an eval folder, or a dataset's .aerobench/)")
    p.add_argument("--label", default=None, help="leaderboard row name (default: the policy name)")
    p.add_argument("--out", required=True, help="results file to write")
    p.set_defaults(func=_run_summarize)


def _run_summarize(args) -> int:
    from ..eval.evaluate import format_table
    from ..eval.results import summarize, write_results
    from ..export.card import generate_command
    from ..rollout.records import RECORDS_FILE, read_records

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


def add_compare(sub) -> None:
    p = sub.add_parser("compare", help="two evals on the same starts, episode by episode: paired table, exact McNemar "
                       "p-value, 95%% interval for the difference, verdict")
    p.add_argument("a", help="eval folder or results file of policy A")
    p.add_argument("b", help="eval folder or results file of policy B (same setting, skills, objects and --seed)")
    p.add_argument("--difference", type=float, default=0.10,
                   help="success-rate difference the power statement is about (default: 0.10, ten points)")
    p.add_argument("--diagnostic", default=None,
                   help="compare a record diagnostic start by start instead of success (e.g. "
                        "min_tcp_to_grasp_point_m): medians, A lower on k of n, Wilcoxon signed-rank p; eval folders")
    p.add_argument("--json", default=None, help="also write the comparison to this JSON file")
    p.set_defaults(func=_run_compare)


def _run_compare(args) -> int:
    from ..eval.compare import compare, compare_diagnostic, format_comparison, format_diagnostic

    try:
        if args.diagnostic:
            result = compare_diagnostic(args.a, args.b, args.diagnostic)
        else:
            result = compare(args.a, args.b, difference=args.difference)
    except ValueError as e:
        raise UserError(str(e)) from None
    print(format_diagnostic(result) if args.diagnostic else format_comparison(result))
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return 0


def add_plan(sub) -> None:
    p = sub.add_parser("plan", help="episodes per cell that detect a success-rate difference with a given power "
                       "(the exact McNemar test of aerobench compare)")
    p.add_argument("--baseline", type=float, required=True, help="the success rate to compare against, e.g. 0.8")
    p.add_argument("--difference", type=float, required=True,
                   help="the difference in success rate to detect, e.g. 0.1 (both directions, the test is two-sided)")
    p.add_argument("--power", type=float, default=0.8, help="chance of detecting it (default: 0.8)")
    p.add_argument("--alpha", type=float, default=0.05, help="two-sided significance level (default: 0.05)")
    p.add_argument("--cells", type=int, default=1, help="cells tested together: each at alpha / cells, the strictest "
                   "step of the Holm correction (default: 1)")
    p.add_argument("--discordant", type=float, default=None,
                   help="share of paired episodes the two policies disagree on, e.g. (A only + B only) / n of a pilot "
                        "compare (default: their outcomes independent given the start)")
    p.set_defaults(func=_run_plan)


def _run_plan(args) -> int:
    from ..eval.plan import format_plan, plan

    try:
        plans = plan(args.baseline, args.difference, args.power, args.alpha, args.cells, args.discordant)
    except ValueError as e:
        raise UserError(str(e)) from None
    print(format_plan(plans, args.power, args.alpha, args.cells, args.discordant))
    return 0


def add_leaderboard(sub) -> None:
    p = sub.add_parser("leaderboard", help="render Markdown, LaTeX and HTML leaderboards from results files")
    p.add_argument("results", nargs="+", help="results.json files written by aerobench eval")
    p.add_argument("--out", default="leaderboards", help="output folder")
    p.set_defaults(func=_run_leaderboard)


def _run_leaderboard(args) -> int:
    from ..eval.leaderboard_folder import build_leaderboard

    try:
        written = build_leaderboard(args.results, args.out)
    except ValueError as e:
        raise UserError(str(e)) from None
    print("wrote " + ", ".join(str(p) for p in written.values()))
    print(f"HTML leaderboard: {Path(args.out) / 'index.html'}")
    return 0


def add_publish(sub) -> None:
    p = sub.add_parser("publish", help="copy an eval's results file into a leaderboard folder, with rollout videos of "
                       "the row's own starts")
    p.add_argument("eval_dir", help="the row's eval folder (or its results.json)")
    p.add_argument("--to", required=True, help="the results file to write, e.g. leaderboards/results/TidyHouse_expert.json "
                   "(videos go to the sibling folder <name>_videos/)")
    p.add_argument("--videos-from", default=None, help="a second eval of the same policy, checkpoint, setting and "
                   "--seed made with --video N (default: the row's own videos)")
    p.set_defaults(func=_run_publish)


def _run_publish(args) -> int:
    from ..eval.publish import publish

    try:
        published = publish(args.eval_dir, args.to, args.videos_from)
    except ValueError as e:
        raise UserError(str(e)) from None
    print(f"wrote {args.to} ({len(published.get('videos', []))} videos)")
    return 0
