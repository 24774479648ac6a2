"""`aerobench fly` and `aerobench render`: one flight-test scenario, one picture of an env."""

from __future__ import annotations

from pathlib import Path

from .common import UserError, print_metrics


def add_fly(sub) -> None:
    from ..envs.platforms import PLATFORMS
    from ..flight.scenarios import SCENARIOS

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
    from ..flight.runner import FlightRequest, fly

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
    print_metrics(result.metrics, as_json=args.json)
    return 0


AERO_ENV_IDS = ("AeroPick-v1", "AeroPlace-v1", "AeroNav-v1", "AeroOpen-v1", "AeroClose-v1", "AeroSequential-v1", "AeroFly-v1")


def add_render(sub) -> None:
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

    from ..envs.views import render_env

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

