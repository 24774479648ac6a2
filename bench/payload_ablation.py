"""The spec's payload ablation (appendix "Payload-Aware Flight Control"): the expert's chained pick -> transport ->
place in TidyHouse on the same instances, seeds and start states, with the payload-aware and with the nominal
controller (the two differ only in the payload switches; the release's stiff gains act in both).

Episodes run through the product's rollout runner under the spec's chained protocol (stage budgets 400 / 1200 / 1000
control steps, the transport grasp-hold check), sharded over worker processes; every finished episode is appended to
a per-shard JSON-lines file, so an interrupted run resumes without repeating or losing episodes. Prints and writes:
- the outcome table (success, grasp lost, collision during pick / transport, timeout, initialization rejections);
- per condition and per object class (sorted by mass): median grasp-to-lift-off time (lift-off: the object 5 cm above
  where it was grasped; an episode that never lifts it counts as never), mean |xi_z| and RMS tilt rate during the carry
  (grasp handoff to the start of placement), success;
- one carry chosen by the spec's fixed rule (among heavy-can instances that succeed with payload-aware control and
  lose the grasp under the nominal controller, the one with the median nominal episode length): object height, xi_z,
  slip in the jaws and tilt, aligned at the grasp;
- the tilt-rate PSD of carries lasting at least 6.4 s (Welch, 6.4 s segments at 20 Hz; pointwise median and 25-75%).

    python bench/payload_ablation.py --spec-scale --workers 2 --out outputs/bench/payload_ablation_spec  # 14 x 9 x 2
    python bench/payload_ablation.py --instances-per-object 1   # a quick look
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import numpy as np  # noqa: E402

from aerobench.envs.checks import FailureCause  # noqa: E402
from aerobench.envs.objects import OBJECTS  # noqa: E402
from aerobench.envs.platforms import CONTROL_HZ, get_platform  # noqa: E402

SETTING, CHAIN = "TidyHouse", "pick,transport,place"
CONDITIONS = ("payload-aware", "nominal")
SPEC_INSTANCES_PER_OBJECT = 14  # "126 TidyHouse instances (nine object classes, 14 instances each)"
LIFT_OFF_M = 0.05  # "the first time after the grasp at which the object has risen 5 cm"
PSD_SEGMENT_S = 6.4  # "Welch's method with 6.4 s segments sampled at 20 Hz"; carries shorter than this are left out
# "the three filled cans (0.37-0.40 kg)": the heavy cans of the spec's single-carry rule
HEAVY_CANS = tuple(name for name, o in OBJECTS.items() if name.endswith("_can") and o.mass_kg >= 0.35)
SIGNALS = ("subtask_index", "fail_cause", "is_grasped", "object_height", "tcp_height", "integral_z", "tilt", "tilt_rate")
OUTCOME_ROWS = ("success", "grasp lost", "collision (pick)", "collision (transport)", "timeout", "other",
                "initialization rejection")


# ---------------------------------------------------------------------------------------------------------------- run
class JsonLinesSink:
    """One JSON line per finished episode (its record and the kept signals); resumable (`done_indices`)."""

    def __init__(self, path: Path):
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)

    def done_indices(self) -> set[int]:
        return {e["index"] for e in read_lines(self.path)}

    def write(self, episode) -> None:
        record = json.loads(episode.record.to_json())
        line = dict(index=record["episode_index"], seed=record["seed"], object=record["object"], record=record,
                    init_failed=bool(episode.extra.get("init_failed")),
                    signals={k: np.round(v.astype(float), 5).tolist() for k, v in episode.signals.items()})
        with open(self.path, "a") as f:
            f.write(json.dumps(line) + "\n")
            f.flush()
            os.fsync(f.fileno())

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


def read_lines(path: Path) -> list[dict]:
    """The complete lines of a shard file (a line cut by a crash is ignored and its episode re-run)."""
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out


def run_shard(condition: str, shard: int, shards: int, episodes: int, seed: int, out: str) -> str:
    """Run one contiguous block of a condition's episodes (a worker process)."""
    import aerobench.envs  # noqa: F401  (registers the envs in this process)
    from aerobench.rollout.chained import resolve_chain
    from aerobench.rollout.runner import RolloutRunner, RolloutSpec

    path = Path(out) / "episodes" / condition / f"shard_{shard:02d}_of_{shards:02d}.jsonl"
    sink = JsonLinesSink(path)
    lines = read_lines(path)  # a cut last line is rewritten whole before new ones are appended
    path.write_text("".join(json.dumps(e) + "\n" for e in lines))
    spec = RolloutSpec(
        setting=SETTING, skills=(resolve_chain(SETTING, CHAIN.split(",")),), episodes=episodes, seed=seed,
        shard=(shard, shards), policy="expert", record_cameras=False, controller=condition, chained=True,
        keep_signals=SIGNALS,
    )
    run_file = path.parent / "run.json"  # the folder's run: resuming under other settings (e.g. solver) is refused
    run = {k: v for k, v in spec.as_dict().items() if k != "shard"}
    if run_file.exists() and json.loads(run_file.read_text()) != run:
        raise SystemExit(f"{path.parent} holds a different run ({run_file}); use another --out")
    run_file.write_text(json.dumps(run, indent=1) + "\n")
    RolloutRunner(spec, sink, on_episode=lambda ep, p: print(
        f"{condition:14s} {ep.record.object:18s} seed {ep.record.seed}: {ep.record.outcome} {ep.record.mode}", flush=True,
    )).run()
    return str(path)


def run_all(instances: int, seed: int, out: Path, workers: int, shards: int) -> dict[str, list[dict]]:
    episodes = instances * len(OBJECTS)  # the plan cycles the objects: `instances` per class, same seeds per condition
    jobs = [(c, i, shards, episodes, seed, str(out)) for c in CONDITIONS for i in range(shards)]
    if workers <= 1:
        for job in jobs:
            run_shard(*job)
    else:
        with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
            for future in [pool.submit(run_shard, *job) for job in jobs]:
                future.result()
    results = {}
    for c in CONDITIONS:
        lines = [e for i in range(shards) for e in read_lines(out / "episodes" / c / f"shard_{i:02d}_of_{shards:02d}.jsonl")]
        results[c] = sorted(lines, key=lambda e: e["index"])
    return results


# ------------------------------------------------------------------------------------------------------------ analysis
def outcome_row(ep: dict) -> str:
    if ep["init_failed"]:
        return "initialization rejection"
    if ep["record"]["outcome"] == "S":
        return "success"
    s = ep["signals"]
    cause = FailureCause(int(s["fail_cause"][-1])).label if s.get("fail_cause") else ""
    if cause in ("fail_object_drop", "fail_unsupported_release"):
        return "grasp lost"
    if cause in ("collision", "fail_collision_force"):
        return "collision (pick)" if int(s["subtask_index"][-1]) == 0 else "collision (transport)"
    return "timeout" if not cause else "other"


def episode_metrics(ep: dict) -> dict:
    """Grasp, lift-off, carry and slip of one episode (None where it never got there)."""
    s = {k: np.asarray(v, dtype=float) for k, v in ep["signals"].items()}
    out = dict(object=ep["object"], seed=ep["seed"], index=ep["index"], outcome=outcome_row(ep),
               steps=len(ep["signals"].get("tilt", [])), grasp_step=None, lift_off_s=None, never_lifted=False,
               carry_steps=0, mean_abs_xi_z=None, rms_tilt_rate=None)
    if ep["init_failed"] or not len(s.get("is_grasped", [])) or not s["is_grasped"].any():
        return out
    t_grasp = int(np.argmax(s["is_grasped"] > 0.5))
    out["grasp_step"] = t_grasp
    risen = np.nonzero(s["object_height"][t_grasp:] >= s["object_height"][t_grasp] + LIFT_OFF_M)[0]
    if len(risen):
        out["lift_off_s"] = float(risen[0]) / CONTROL_HZ
    else:
        out["never_lifted"] = True
    stage = s["subtask_index"]
    handoff, placing = np.nonzero(stage >= 1)[0], np.nonzero(stage >= 2)[0]
    if len(handoff):
        t0 = int(handoff[0])
        t1 = int(placing[0]) if len(placing) else len(stage)
        if t1 > t0:
            out["carry_steps"] = t1 - t0
            out["mean_abs_xi_z"] = float(np.mean(np.abs(s["integral_z"][t0:t1])))
            out["rms_tilt_rate"] = float(np.degrees(np.sqrt(np.mean(np.square(s["tilt_rate"][t0:t1])))))
            out["_carry"] = (t0, t1)
    return out


def median_lift_off(metrics: list[dict]) -> tuple[float | None, bool]:
    """Median grasp-to-lift-off over grasped episodes, a never-lifted one counting as infinitely late."""
    values = [math.inf if m["never_lifted"] else m["lift_off_s"] for m in metrics if m["grasp_step"] is not None]
    if not values:
        return None, False
    med = float(np.median(values))
    return (None, True) if math.isinf(med) else (med, False)


def mean_of(metrics: list[dict], key: str) -> float | None:
    values = [m[key] for m in metrics if m[key] is not None]
    return float(np.mean(values)) if values else None


def summarize(metrics: list[dict]) -> dict:
    lift, never = median_lift_off(metrics)
    evaluated = [m for m in metrics if m["outcome"] != "initialization rejection"]
    return dict(
        n=len(metrics), evaluated=len(evaluated), success=sum(m["outcome"] == "success" for m in metrics),
        success_rate=(sum(m["outcome"] == "success" for m in evaluated) / len(evaluated)) if evaluated else None,
        median_lift_off_s=lift, median_never_lifts=never, mean_abs_xi_z=mean_of(metrics, "mean_abs_xi_z"),
        rms_tilt_rate=mean_of(metrics, "rms_tilt_rate"), reached_carry=sum(m["carry_steps"] > 0 for m in metrics),
    )


def single_carry(results: dict[str, list[dict]], metrics: dict[str, list[dict]]) -> dict | None:
    """The spec's fixed rule, else (stated) the nearest relaxation: heavy cans that succeed payload-aware, median
    nominal episode length."""
    aware = {m["index"]: m for m in metrics["payload-aware"]}
    nominal = {m["index"]: m for m in metrics["nominal"]}
    rules = (("succeeds payload-aware and loses the grasp nominal", lambda a, n: n["outcome"] == "grasp lost"),
             ("succeeds payload-aware and fails nominal (no instance loses the grasp)", lambda a, n: n["outcome"] != "success"),
             ("succeeds payload-aware (none fails nominal)", lambda a, n: True))
    for rule, keep in rules:
        pool = [i for i, a in aware.items() if a["object"] in HEAVY_CANS and a["outcome"] == "success" and i in nominal
                and nominal[i]["grasp_step"] is not None and keep(a, nominal[i])]
        if pool:
            pool.sort(key=lambda i: (nominal[i]["steps"], i))
            index = pool[(len(pool) - 1) // 2]
            series = {}
            for c in CONDITIONS:
                ep = next(e for e in results[c] if e["index"] == index)
                s = {k: np.asarray(v, dtype=float) for k, v in ep["signals"].items()}
                t0 = int(np.argmax(s["is_grasped"] > 0.5))
                lost = None
                if outcome_row(ep) == "grasp lost":
                    lost = (len(s["is_grasped"]) - 1 - t0) / CONTROL_HZ
                series[c] = dict(
                    t=((np.arange(len(s["tilt"])) - t0) / CONTROL_HZ).round(3).tolist(),
                    height=(s["object_height"] - s["object_height"][0]).round(4).tolist(),
                    integral_z=s["integral_z"].round(4).tolist(),
                    # slip: the object's height relative to the TCP from its value at the grasp, while grasped
                    slip=np.where(s["is_grasped"] > 0.5, (s["object_height"] - s["tcp_height"])
                                  - (s["object_height"][t0] - s["tcp_height"][t0]), np.nan).round(4),
                    tilt_deg=np.degrees(s["tilt"]).round(3).tolist(), grasp_lost_s=lost, outcome=outcome_row(ep),
                    lift_off_s=next(m for m in metrics[c] if m["index"] == index)["lift_off_s"],
                )
            for c in CONDITIONS:  # JSON has no NaN: no slip reads null
                series[c]["slip"] = [None if math.isnan(v) else float(v) for v in series[c]["slip"]]
            return dict(rule=rule, candidates=len(pool), index=index, object=aware[index]["object"],
                        seed=aware[index]["seed"], series=series)
    return None


def tilt_rate_psd(results: dict[str, list[dict]], metrics: dict[str, list[dict]]) -> dict:
    """Welch PSD of the carry's tilt rate per episode (deg/s, 6.4 s segments at 20 Hz), median and 25-75% per condition."""
    from scipy.signal import welch

    nperseg = int(round(PSD_SEGMENT_S * CONTROL_HZ))
    out: dict = {}
    for c in CONDITIONS:
        spectra, freqs = [], None
        for ep, m in zip(results[c], metrics[c]):
            if "_carry" not in m or m["carry_steps"] < nperseg:
                continue
            t0, t1 = m["_carry"]
            x = np.degrees(np.asarray(ep["signals"]["tilt_rate"][t0:t1], dtype=float))
            freqs, pxx = welch(x, fs=CONTROL_HZ, nperseg=nperseg)
            spectra.append(pxx)
        if not spectra:
            out[c] = dict(episodes=0)
            continue
        q25, med, q75 = np.percentile(np.stack(spectra), [25, 50, 75], axis=0)
        out[c] = dict(episodes=len(spectra), freq_hz=freqs.round(4).tolist(), median=med.tolist(), q25=q25.tolist(),
                      q75=q75.tolist())
    nominal = out.get("nominal", {})
    if nominal.get("episodes"):
        f, med = np.asarray(nominal["freq_hz"]), np.asarray(nominal["median"])
        band = f > 0.3  # above the carry's slow manoeuvres
        k = int(np.nonzero(band)[0][np.argmax(med[band])])
        out["nominal_peak"] = dict(freq_hz=float(f[k]), nominal=float(med[k]))
        if out.get("payload-aware", {}).get("episodes"):
            out["nominal_peak"]["payload_aware"] = float(out["payload-aware"]["median"][k])
        for c in CONDITIONS:
            if out[c].get("episodes"):
                sel = (np.asarray(out[c]["freq_hz"]) >= 2) & (np.asarray(out[c]["freq_hz"]) <= 5)
                out[c]["mean_2_5_hz"] = float(np.mean(np.asarray(out[c]["median"])[sel]))
    return out


def analyse(results: dict[str, list[dict]]) -> dict:
    metrics = {c: [episode_metrics(e) for e in results[c]] for c in CONDITIONS}
    rejected = {c: {m["index"] for m in metrics[c] if m["outcome"] == "initialization rejection"} for c in CONDITIONS}
    summary: dict = dict(
        protocol=dict(setting=SETTING, chain=CHAIN, instances_per_object=len(results[CONDITIONS[0]]) // len(OBJECTS),
                      same_rejections_in_both=rejected[CONDITIONS[0]] == rejected[CONDITIONS[1]]),
        outcomes={c: {row: sum(m["outcome"] == row for m in metrics[c]) for row in OUTCOME_ROWS} for c in CONDITIONS},
        overall={c: summarize(metrics[c]) for c in CONDITIONS},
        per_object={c: {o: summarize([m for m in metrics[c] if m["object"] == o]) for o in OBJECTS} for c in CONDITIONS},
        episodes={c: [{k: v for k, v in m.items() if not k.startswith("_")} for m in metrics[c]] for c in CONDITIONS},
    )
    summary["single_carry"] = single_carry(results, metrics)
    summary["psd"] = tilt_rate_psd(results, metrics)
    return summary


# --------------------------------------------------------------------------------------------------------------- print
def report(summary: dict) -> None:
    fmt = lambda v, p=2: "-" if v is None else f"{v:.{p}f}"  # noqa: E731
    print(f"\n{'outcome':26s}" + "".join(f"{c:>16s}" for c in CONDITIONS))
    for row in OUTCOME_ROWS:
        print(f"{row:26s}" + "".join(f"{summary['outcomes'][c][row]:16d}" for c in CONDITIONS))
    print(f"\n{'overall':26s}{'success':>12s}{'lift-off s':>12s}{'|xi_z| carry':>14s}{'RMS tilt deg/s':>16s}")
    for c in CONDITIONS:
        o = summary["overall"][c]
        lift = "never" if o["median_never_lifts"] else fmt(o["median_lift_off_s"])
        print(f"{c:26s}{o['success']:>5d}/{o['evaluated']:<6d}{lift:>12s}{fmt(o['mean_abs_xi_z']):>14s}"
              f"{fmt(o['rms_tilt_rate']):>16s}")
    print(f"\n{'per object (by mass)':26s}" + "".join(f"{c + ' ok, lift, xi, tilt':>36s}" for c in CONDITIONS))
    for obj in sorted(OBJECTS, key=lambda o: OBJECTS[o].mass_kg):
        cells = []
        for c in CONDITIONS:
            o = summary["per_object"][c][obj]
            lift = "never" if o["median_never_lifts"] else fmt(o["median_lift_off_s"], 1)
            cells.append(f"{o['success']:>3d}/{o['evaluated']:<3d}{lift:>7s}{fmt(o['mean_abs_xi_z']):>7s}"
                         f"{fmt(o['rms_tilt_rate'], 1):>7s}")
        print(f"{obj + f' ({OBJECTS[obj].mass_kg:.2f})':26s}" + "".join(f"{cell:>36s}" for cell in cells))
    carry = summary["single_carry"]
    if carry:
        print(f"\nsingle carry: {carry['object']} seed {carry['seed']} ({carry['rule']}; {carry['candidates']} candidates)")
        for c in CONDITIONS:
            s = carry["series"][c]
            print(f"  {c:14s} {s['outcome']:22s} lift-off {fmt(s['lift_off_s'])} s, grasp lost at {fmt(s['grasp_lost_s'])} s, "
                  f"max |xi_z| {max(map(abs, s['integral_z'])):.2f}, max tilt {max(s['tilt_deg']):.1f} deg")
    psd = summary["psd"]
    print("\ntilt-rate PSD: carries >= 6.4 s: " + ", ".join(f"{c} {psd[c]['episodes']}" for c in CONDITIONS))
    if "nominal_peak" in psd:
        p = psd["nominal_peak"]
        print(f"  nominal median peak {p['nominal']:.2f} (deg/s)^2/Hz at {p['freq_hz']:.2f} Hz; payload-aware there "
              f"{fmt(p.get('payload_aware'))}; 2-5 Hz mean: " +
              ", ".join(f"{c} {fmt(psd[c].get('mean_2_5_hz'))}" for c in CONDITIONS))


# ---------------------------------------------------------------------------------------------------------------- plot
def plot(summary: dict, out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = dict(zip(CONDITIONS, ("tab:blue", "tab:orange")))
    paths = []
    # per object class, sorted by mass (spec Fig. payload_objects)
    objects = sorted(OBJECTS, key=lambda o: OBJECTS[o].mass_kg)
    panels = (("median_lift_off_s", "grasp to lift-off [s]"), ("mean_abs_xi_z", "mean |xi_z| during carry"),
              ("rms_tilt_rate", "RMS tilt rate during carry [deg/s]"), ("success_rate", "success rate"))
    fig, axes = plt.subplots(1, 4, figsize=(16, 4.8), sharey=True)
    y = np.arange(len(objects))
    for ax, (key, label) in zip(axes, panels):
        for offset, c in zip((-0.15, 0.15), CONDITIONS):
            rows = [summary["per_object"][c][o] for o in objects]
            vals = np.array([np.nan if r[key] is None else r[key] for r in rows], dtype=float)
            ax.scatter(vals, y + offset, color=colors[c], label=c)
            if key == "median_lift_off_s":  # open marker: the median episode never lifts the object
                never = [i for i, r in enumerate(rows) if r["median_never_lifts"]]
                if never:
                    right = np.nanmax([v for v in vals] + [1.0]) * 1.1
                    ax.scatter([right] * len(never), np.array(never) + offset, facecolors="none", edgecolors=colors[c])
        if key == "mean_abs_xi_z":
            ax.axvline(get_platform("gripper").gains.integral_limit, color="gray", ls="--", lw=1)
        ax.set_xlabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_yticks(y, [f"{o} ({OBJECTS[o].mass_kg:.2f} kg)" for o in objects])
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    paths.append(out / "payload_ablation.png")
    fig.savefig(paths[-1], dpi=100)
    plt.close(fig)

    carry = summary["single_carry"]
    if carry:
        fig, axes = plt.subplots(4, 1, figsize=(9, 9), sharex=True)
        labels = (("height", "object height [m]"), ("integral_z", "xi_z [m/s^2]"), ("slip", "slip in jaws [m]"),
                  ("tilt_deg", "tilt [deg]"))
        for c in CONDITIONS:
            s = carry["series"][c]
            for ax, (key, label) in zip(axes, labels):
                ax.plot(s["t"], np.asarray(s[key], dtype=float), color=colors[c], lw=1, label=c)
                if s["grasp_lost_s"] is not None:
                    k = min(range(len(s["t"])), key=lambda i: abs(s["t"][i] - s["grasp_lost_s"]))
                    k = max(i for i in range(k + 1) if s[key][i] is not None)  # the last grasped step for the slip
                    ax.plot([s["t"][k]], [s[key][k]], "x", color=colors[c], ms=8)
                ax.set_ylabel(label)
        limit = get_platform("gripper").gains.integral_limit
        for v in (-limit, limit):
            axes[1].axhline(v, color="gray", ls="--", lw=1)
        axes[-1].set_xlabel("time since grasp [s]")
        axes[-1].set_xlim(left=-2.0)
        axes[0].legend(fontsize=8)
        axes[0].set_title(f"{carry['object']}, seed {carry['seed']} ({carry['rule']})", fontsize=9)
        fig.tight_layout()
        paths.append(out / "payload_timeseries.png")
        fig.savefig(paths[-1], dpi=100)
        plt.close(fig)

    psd = summary["psd"]
    if any(psd[c].get("episodes") for c in CONDITIONS):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for c in CONDITIONS:
            p = psd[c]
            if not p.get("episodes"):
                continue
            ax.semilogy(p["freq_hz"], p["median"], color=colors[c], label=f"{c} ({p['episodes']} carries)")
            ax.fill_between(p["freq_hz"], p["q25"], p["q75"], color=colors[c], alpha=0.25)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("tilt-rate PSD [(deg/s)^2/Hz]")
        ax.legend()
        ax.grid(alpha=0.3)
        fig.tight_layout()
        paths.append(out / "payload_psd.png")
        fig.savefig(paths[-1], dpi=100)
        plt.close(fig)
    return paths


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spec-scale", action="store_true", help=f"{SPEC_INSTANCES_PER_OBJECT} instances per class")
    parser.add_argument("--instances-per-object", type=int, default=1)
    parser.add_argument("--seed", type=int, default=30, help="episode i runs with seed * 1000003 + i in both conditions")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (physx_cpu: one env per process)")
    parser.add_argument("--shards", type=int, default=4, help="blocks per condition (fixed for a run, so it resumes)")
    parser.add_argument("--out", default="outputs/bench/payload_ablation")
    args = parser.parse_args(argv)
    instances = SPEC_INSTANCES_PER_OBJECT if args.spec_scale else args.instances_per_object
    if instances < 1 or args.workers < 1 or args.shards < 1:
        parser.error("--instances-per-object, --workers and --shards must be at least 1")
    out = Path(args.out)
    results = run_all(instances, args.seed, out, args.workers, args.shards)
    summary = analyse(results)
    from aerobench.envs.base_env import default_physx_solver

    summary["protocol"].update(seed=args.seed, physx_solver=default_physx_solver(), command="python bench/payload_ablation.py " +
                               (" ".join(argv) if argv is not None else " ".join(sys.argv[1:])))
    report(summary)
    (out / "payload_ablation.json").write_text(json.dumps(summary, indent=1) + "\n")
    paths = plot(summary, out)
    print(f"\nwrote {out / 'payload_ablation.json'} and " + ", ".join(str(p) for p in paths))


if __name__ == "__main__":
    main()
