"""`aerobench demo`: the platform flies, each setting's start is pictured, a dataset is made and evaluated."""

from __future__ import annotations

import json
from pathlib import Path

from .common import UserError, print_metrics


def add_demo(sub) -> None:
    p = sub.add_parser("demo", help="the gripper platform flies a waypoint square carrying a payload in a room")
    p.add_argument("--out", default="outputs/demo", help="folder for video.mp4, flight.png, metrics.json")
    p.add_argument("--payload-kg", type=float, default=0.37)
    p.add_argument("--no-video", action="store_true", help="skip rendering the videos")
    p.add_argument("--rollout-steps", type=int, default=60, help="length of the random-policy rollout video")
    p.add_argument("--demo-episodes", type=int, default=4, help="expert episodes generated and exported")
    p.add_argument("--eval-episodes-per-object", type=int, default=1, help="episodes per skill-object pair evaluated")
    p.set_defaults(func=_run_demo)


def _run_demo(args) -> int:
    from ..flight.runner import FlightRequest, fly

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
    print_metrics(result.metrics, as_json=False)
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

    from ..envs.views import render_env
    from ..video import write_video

    written = []
    for k, (env_id, kwargs) in enumerate(DEMO_STARTS, 1):
        name = f"start_{kwargs['setting']}_{env_id.removeprefix('Aero').removesuffix('-v1').lower()}.png"
        print(f"picturing each setting's start ({k} of {len(DEMO_STARTS)}): {name} ...", flush=True)
        imageio.imwrite(out / name, render_env(env_id, seed=0, **kwargs))
        written.append(name)
    if not args.no_video:
        print("rendering a random rollout and an expert pick (videos) ...", flush=True)
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

    from ..eval.evaluate import RESULTS_FILE, EvalConfig, evaluate, format_table
    from ..eval.leaderboard_folder import build_leaderboard

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

    from ..export import DatasetSink
    from ..export.info import dataset_info, format_info
    from ..rollout.runner import RolloutRunner, RolloutSpec

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


def rollout_frames(env_id: str, steps: int, seed: int = 0, policy: str = "random", every: int = 1, **kwargs) -> list:
    """Composed pictures (`envs.views`) of one episode of `policy` (a registered policy name), every `every` control
    steps, with a line of progress every 50 steps (rendering them is the demo's slow part)."""
    import gymnasium as gym
    import torch

    import aerobench.envs  # noqa: F401
    from aerobench.envs.views import compose_from_obs
    from aerobench.policies import make_policy

    env = gym.make(env_id, obs_mode="rgbd", render_mode="rgb_array", **kwargs)
    try:
        obs, _ = env.reset(seed=seed)
        actor = make_policy(policy, env.unwrapped, seed=seed) if policy == "random" else make_policy(policy, env.unwrapped)
        actor.reset(torch.arange(1))
        frames = [compose_from_obs(env, obs)]
        for k in range(steps):
            obs, _, terminated, truncated, _ = env.step(actor.act(obs))
            if k % every == 0:
                frames.append(compose_from_obs(env, obs))
            if (k + 1) % 50 == 0:
                print(f"  {policy} in {env_id}: step {k + 1} of at most {steps}", flush=True)
            if bool(terminated[0]) or bool(truncated[0]):
                break
        return frames
    finally:
        env.close()
