"""`aerobench` command line: a thin layer that parses arguments and calls the library.

User mistakes (unknown names, bad numbers) end in one line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path


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

    from .envs.views import random_rollout_frames, render_env
    from .flight.runner import write_video

    written = []
    for env_id, kwargs in DEMO_STARTS:
        name = f"start_{kwargs['setting']}_{env_id.removeprefix('Aero').removesuffix('-v1').lower()}.png"
        imageio.imwrite(out / name, render_env(env_id, seed=0, **kwargs))
        written.append(name)
    if not args.no_video:
        frames = random_rollout_frames("AeroPick-v1", steps=args.rollout_steps, seed=0, setting="TidyHouse")
        write_video(frames, out / "random_rollout.mp4", fps=10)
        written.append("random_rollout.mp4")
    return written


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


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="aerobench", description="aerobench: aerial manipulation benchmark (see README.md)")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_fly(sub)
    _add_demo(sub)
    _add_render(sub)
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


if __name__ == "__main__":
    sys.exit(main())
