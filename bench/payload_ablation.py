"""The spec's payload ablation (appendix "Payload-Aware Flight Control"): the expert's pick -> transport -> place in
TidyHouse on the same instances, seeds and start states, with the payload-aware and with the nominal controller.

Prints the outcome table (success, grasp lost, collision during pick / transport, timeout) and, per condition and per
object class, the median grasp-to-lift-off time (lift-off: the object 5 cm above where it was grasped), the mean
|xi_z| during the carry (grasp handoff to the start of placement) and the RMS tilt rate (roll-pitch angular speed)
during the carry; writes a plot per object class and a JSON of the numbers.

    python bench/payload_ablation.py [--instances-per-object 1] [--out outputs/bench/payload_ablation]
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

import aerobench.envs  # noqa: E402,F401
from aerobench.envs.checks import FailureCause  # noqa: E402
from aerobench.envs.objects import OBJECTS  # noqa: E402
from aerobench.envs.platforms import CONTROL_HZ  # noqa: E402
from aerobench.policies import make_policy  # noqa: E402
from aerobench.rollout.runner import episode_limit  # noqa: E402

LIFT_OFF_M = 0.05  # spec: "the first time after the grasp at which the object has risen 5 cm"
CONDITIONS = ("payload-aware", "nominal")


def run_episode(env, seed: int, obj: str) -> dict:
    env.reset(seed=seed, options={"reconfigure": True, "object": obj})
    base = env.unwrapped
    policy = make_policy("expert", base)
    policy.reset(torch.arange(1))
    xi_z, tilt_rate, height, grasped, stage = [], [], [], [], []
    info = {}
    for _ in range(episode_limit(env)):
        _, _, terminated, truncated, info = env.step(policy.act(None))
        state = base.agent.airframe_state()
        xi_z.append(float(base.agent.body_controller.memory.xi[0, 2]))
        tilt_rate.append(math.degrees(float(torch.linalg.norm(state.angular_velocity_body[0, :2]))))
        height.append(float(info["object_height"][0]))
        grasped.append(bool(info["is_grasped"][0]))
        stage.append(int(info["subtask_index"][0]))
        if terminated[0] or truncated[0]:
            break
    cause = FailureCause(int(info["fail_cause"][0]))
    return dict(
        seed=seed, object=obj, success=bool(info["success"][0]), cause=cause.label, init_failed=bool(info["init_failed"][0]),
        stage=stage[-1], xi_z=xi_z, tilt_rate=tilt_rate, height=height, grasped=grasped, stages=stage,
    )


def carry_metrics(ep: dict) -> dict:
    """Grasp-to-lift-off time and carry statistics of one episode (None where it never got there)."""
    grasped = np.asarray(ep["grasped"])
    if not grasped.any():
        return dict(lift_off_s=None, mean_abs_xi_z=None, rms_tilt_rate=None)
    t_grasp = int(np.argmax(grasped))
    height = np.asarray(ep["height"])
    risen = np.nonzero(height[t_grasp:] >= height[t_grasp] + LIFT_OFF_M)[0]
    lift_off = float(risen[0]) / CONTROL_HZ if len(risen) else None
    stages = np.asarray(ep["stages"])
    place_start = np.nonzero(stages >= 2)[0]
    t_end = int(place_start[0]) if len(place_start) else len(stages)
    carry = slice(t_grasp, max(t_end, t_grasp + 1))
    return dict(
        lift_off_s=lift_off,
        mean_abs_xi_z=float(np.mean(np.abs(ep["xi_z"][carry]))),
        rms_tilt_rate=float(np.sqrt(np.mean(np.square(ep["tilt_rate"][carry])))),
    )


def outcome_row(ep: dict) -> str:
    if ep["init_failed"]:
        return "initialization failure"
    if ep["success"]:
        return "success"
    if ep["cause"] in ("fail_object_drop", "fail_unsupported_release"):
        return "grasp lost"
    if ep["cause"] in ("collision", "fail_collision_force"):
        return "collision (pick)" if ep["stage"] == 0 else "collision (transport)"
    return "timeout" if not ep["cause"] else f"other ({ep['cause']})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--instances-per-object", type=int, default=1)
    parser.add_argument("--out", default="outputs/bench/payload_ablation")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, list[dict]] = {}
    for condition in CONDITIONS:
        env = gym.make("AeroSequential-v1", setting="TidyHouse", obs_mode="state_dict", controller=condition)
        episodes = []
        for k in range(args.instances_per_object):
            for j, obj in enumerate(OBJECTS):
                ep = run_episode(env, seed=1000 + k * len(OBJECTS) + j, obj=obj)
                ep.update(carry_metrics(ep))
                episodes.append(ep)
                print(f"{condition:14s} {obj:18s} seed {ep['seed']}: {outcome_row(ep)}", flush=True)
        env.close()
        results[condition] = episodes

    rows = ("success", "grasp lost", "collision (pick)", "collision (transport)", "timeout")
    print(f"\n{'outcome':24s}" + "".join(f"{c:>16s}" for c in CONDITIONS))
    for row in rows:
        counts = [sum(outcome_row(e) == row for e in results[c]) for c in CONDITIONS]
        print(f"{row:24s}" + "".join(f"{n:16d}" for n in counts))
    others = [[e for e in results[c] if outcome_row(e) not in rows] for c in CONDITIONS]
    print(f"{'other / init failure':24s}" + "".join(f"{len(o):16d}" for o in others))

    def median(values):
        values = [v for v in values if v is not None]
        return float(np.median(values)) if values else None

    summary: dict = {}
    print(f"\n{'per condition':24s}{'lift-off s':>12s}{'|xi_z| carry':>14s}{'RMS tilt deg/s':>16s}")
    for c in CONDITIONS:
        eps = results[c]
        s = dict(
            success=sum(e["success"] for e in eps), n=len(eps),
            median_lift_off_s=median([e["lift_off_s"] for e in eps]),
            mean_abs_xi_z=median([e["mean_abs_xi_z"] for e in eps]),
            rms_tilt_rate=median([e["rms_tilt_rate"] for e in eps]),
            per_object={},
        )
        for obj in OBJECTS:
            oe = [e for e in eps if e["object"] == obj]
            s["per_object"][obj] = dict(
                success=sum(e["success"] for e in oe), n=len(oe),
                median_lift_off_s=median([e["lift_off_s"] for e in oe]),
                mean_abs_xi_z=median([e["mean_abs_xi_z"] for e in oe]),
                rms_tilt_rate=median([e["rms_tilt_rate"] for e in oe]),
            )
        summary[c] = s
        fmt = lambda v: f"{v:.2f}" if v is not None else "-"  # noqa: E731
        print(f"{c:24s}{fmt(s['median_lift_off_s']):>12s}{fmt(s['mean_abs_xi_z']):>14s}{fmt(s['rms_tilt_rate']):>16s}")
    (out / "payload_ablation.json").write_text(json.dumps(summary, indent=2) + "\n")
    plot(summary, out / "payload_ablation.png")
    print(f"\nwrote {out / 'payload_ablation.json'} and {out / 'payload_ablation.png'}")


def plot(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    objects = sorted(OBJECTS, key=lambda o: OBJECTS[o].mass_kg)
    panels = (("median_lift_off_s", "grasp to lift-off [s]"), ("mean_abs_xi_z", "mean |xi_z| carry"),
              ("rms_tilt_rate", "RMS tilt rate [deg/s]"), ("success", "success rate"))
    fig, axes = plt.subplots(1, 4, figsize=(16, 4.5), sharey=True)
    y = np.arange(len(objects))
    for ax, (key, label) in zip(axes, panels):
        for offset, (c, marker) in zip((-0.15, 0.15), zip(CONDITIONS, ("o", "s"))):
            values = []
            for o in objects:
                row = summary[c]["per_object"][o]
                v = row["success"] / max(row["n"], 1) if key == "success" else row[key]
                values.append(np.nan if v is None else v)
            ax.scatter(values, y + offset, marker=marker, label=c)
        ax.set_xlabel(label)
    axes[0].set_yticks(y, [f"{o} ({OBJECTS[o].mass_kg:.2f} kg)" for o in objects])
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main()
