"""The spec's trajectory-diversity and execution-efficiency figures (Sec. "Evaluation of Data Generation Strategies",
Figs. trajectory_diversity and ppo_efficiency) for the expert, BC and PPO on Pick.

Each policy runs the same seeded Pick starts through the rollout runner, which here also records the tool centre
point and the planned grasp point every control step. Approach segments (spawn -> within 5 cm of the grasp point
planned at spawn) are drawn in the start-normalized X-Z frame; coverage (occupied 0.05 x 0.05 cells),
36-bin velocity-direction entropy and deviation from the policy's own mean path are estimated on random subsets
(mean and 95% interval); the time to success of successful episodes is split into approach, alignment, grasp, lift
and hold (`aerobench/eval/metrics.py`). Writes `diversity.json`, `diversity.png` (paths and metrics) and
`diversity_efficiency.png` (phase times and episode lengths) under `--out`.

BC and PPO checkpoints are given with `--bc-checkpoint` / `--ppo-checkpoint`, or trained here on a small budget
(BC on `--bc-rollouts` expert rollouts, PPO from scratch for `--ppo-steps` interactions). Defaults are a small CPU
budget (one object class, 8 episodes per policy, BC on 8 expert rollouts for 2000 steps, PPO 2000 interactions);
`--spec-scale` sets every object, 256 episodes per policy (200 subsets of 80 paths) and the spec-scale BC and PPO. Rerunning the same
command continues: checkpoints and every policy's records already in `--out` are reused.

    python bench/diversity.py [--episodes 8] [--bc-checkpoint DIR] [--ppo-checkpoint DIR] [--out DIR]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import learning_curves as lc  # noqa: E402  (shares collection and training with the learning-curve bench)

from aerobench.eval.metrics import (  # noqa: E402
    PHASES,
    approach_segment,
    coverage,
    direction_entropy,
    mean_path_deviation,
    mean_phase_durations,
    normalize_path,
    phase_durations,
    subset_estimate,
)
from aerobench.rollout.episode import EVENT_FLAGS, EpisodeData  # noqa: E402
from aerobench.rollout.records import RecordSink, read_records  # noqa: E402
from aerobench.rollout.runner import RolloutRunner, RolloutSpec  # noqa: E402

SKILL = "pick"
DIVERSITY_SEED = 4_100  # the starts every policy is measured on (not a collection or held-out seed; < 4294)
POLICIES = ("expert", "bc", "ppo")
METRICS = {"coverage_cells": coverage, "direction_entropy_bits": direction_entropy, "mean_path_deviation": mean_path_deviation}

# The spec's numbers ("Trajectory diversity" and "Execution efficiency" paragraphs; mean path deviation is shown
# only as bars in the figure, without numbers in the text).
SPEC = {
    "TidyHouse": {
        "coverage_cells": {"expert": 53, "bc": 77, "ppo": 205},
        "direction_entropy_bits": {"expert": 1.8, "bc": 2.0, "ppo": 3.0},
        "time_to_success_s": {"expert": 15.8, "bc": 15.8, "ppo": 3.8},
        "approach_s": {"expert": 11.4, "bc": 11.4, "ppo": 2.5},
    },
    "PrepareGroceries": {
        "coverage_cells": {"expert": 46, "bc": 71, "ppo": 283},
        "direction_entropy_bits": {"expert": 1.7, "bc": 1.7, "ppo": 3.7},
        "time_to_success_s": {"expert": 14.7, "bc": 14.6, "ppo": 4.0},
        "approach_s": {"expert": 10.1, "bc": 10.1, "ppo": 2.5},
    },
    "note": "approach_s for expert and BC: the text gives one value ('decreases from 11.4 s to 2.5 s'); "
            "subsets: 200 random subsets of 80 episodes per policy",
}


# ── recording paths with the shared runner ───────────────────────────────────────────────────────────────────────
class PathRunner(RolloutRunner):
    """The rollout runner, also recording per step the tool centre point and the object's grasp point (world, m).

    `EpisodeData.frames` carries the proprio state but neither point, so the frame gains two arrays; everything
    else (seeding, outcome annotation, resume) is the runner's own."""

    def _frame(self, obs, action, policy, base) -> dict:
        from aerobench.envs.control.so3 import quat_wxyz_to_matrix

        frame = super()._frame(obs, action, policy, base)
        pose = base.target.pose
        rotation = quat_wxyz_to_matrix(pose.q)
        grasp = pose.p + (rotation @ base.target_grasp_point[..., None])[..., 0]  # as the env's StepContext
        frame["tcp"] = base.agent.tcp_pose.p.detach().double()
        frame["grasp_point"] = grasp.detach().double()
        return frame


def phase_boundaries(frames: dict[str, np.ndarray], steps: int, success: bool, approach_end: int | None) -> list:
    """Control steps elapsed when approach, alignment, grasp, lift and hold end (None: not observed).

    approach: the TCP first within 5 cm of the planned grasp point; alignment: the gripper starts the closing
    command that leads to the first grasp; grasp: first grasped (both fingers >= 0.5 N); lift: first lifted 10 cm
    after the grasp; hold: the success step. Event flags are the env's info after step t, so they count t + 1.
    """
    events = frames["events"]
    grasped = np.flatnonzero(events[:, EVENT_FLAGS.index("is_grasped")] > 0.5)
    grasp_end = int(grasped[0]) + 1 if grasped.size else None
    align_end = lift_end = None
    if grasp_end is not None:
        opening = np.flatnonzero(frames["action"][: grasp_end, -1] >= 0)  # u_g >= 0 commands open
        align_end = int(opening[-1]) + 1 if opening.size else 0
        lifted = np.flatnonzero(events[grasp_end - 1 :, EVENT_FLAGS.index("is_lifted")] > 0.5)
        lift_end = grasp_end + int(lifted[0]) if lifted.size else None
    return [approach_end, align_end, grasp_end, lift_end, steps if success else None]


def trajectory_summary(episode: EpisodeData) -> dict:
    """What the metrics need from one episode: its approach path (world, mm precision), grasp point, phase ends."""
    frames, record = episode.frames, episode.record
    if not record.steps:
        return {"approach": None, "grasp": None, "boundaries": [None] * len(PHASES)}
    tcp, grasp = frames["tcp"], frames["grasp_point"][0]  # the grasp planned at spawn (object at rest)
    segment = approach_segment(tcp, grasp)
    approach_end = len(segment) - 1 if segment is not None else None
    return {
        "approach": np.round(segment, 4).tolist() if segment is not None else None,
        "grasp": np.round(grasp, 4).tolist(),
        "boundaries": phase_boundaries(frames, record.steps, record.outcome == "S", approach_end),
    }


class PathSink(RecordSink):
    """Episode records with the trajectory summary in `extra`: a path is on disk exactly when its record is."""

    def write(self, episode: EpisodeData) -> None:
        episode.extra["trajectory"] = trajectory_summary(episode)
        super().write(episode)


def run_policy(setting: str, objects, episodes: int, policy: str, checkpoint: Path | None, out: Path,
               max_steps: int | None = None) -> list[dict]:
    """The policy's Pick episodes on the diversity starts; their record rows (resumes in `out`)."""
    from aerobench.policies import policy_needs_images

    ckpt = str(checkpoint) if checkpoint else None
    spec = RolloutSpec(setting=setting, skills=(SKILL,), episodes=episodes, objects=objects, seed=DIVERSITY_SEED,
                       policy=policy, checkpoint=ckpt, record_cameras=policy_needs_images(policy, ckpt),
                       max_steps=max_steps)
    sink = PathSink(out, {**spec.as_dict(), "bench": "diversity"})
    started = time.monotonic()
    progress = PathRunner(spec, sink).run()
    elapsed = time.monotonic() - started
    if progress.run_done:
        print(f"  {policy}: {progress.run_done} episodes in {elapsed:.0f} s ({60 * progress.run_done / elapsed:.1f}/min)",
              flush=True)
    return read_records(sink.path)


# ── metrics ──────────────────────────────────────────────────────────────────────────────────────────────────────
def normalized_paths(rows: list[dict]) -> list[np.ndarray]:
    """Start-normalized X-Z approach paths of the episodes whose TCP reached the grasp point (5 cm)."""
    paths = []
    for row in rows:
        t = row["extra"]["trajectory"]
        if t["approach"] is None or len(t["approach"]) < 2:
            continue
        try:
            paths.append(normalize_path(np.asarray(t["approach"]), np.asarray(t["grasp"])))
        except ValueError:  # spawned level with or right above the grasp point: no normalized frame
            continue
    return paths


def measure(rows: list[dict], subsets: int, subset_size: int, seed: int, dt: float) -> dict:
    paths = normalized_paths(rows)
    executed = [r for r in rows if r["outcome"] != "I"]
    successes = [r for r in executed if r["outcome"] == "S"]
    out: dict = {"episodes": len(executed), "successes": len(successes), "approach_paths": len(paths),
                 "init_failures": len(rows) - len(executed)}
    for name, metric in METRICS.items():
        out[name] = subset_estimate(paths, metric, subsets, subset_size, seed).as_dict() if len(paths) >= 2 else None
    durations = [phase_durations(r["extra"]["trajectory"]["boundaries"], dt) for r in successes]
    out["time_to_success_s"] = mean_phase_durations(durations) if successes else None
    out["success_lengths_s"] = [r["steps"] * dt for r in successes]
    return out


# ── the experiment ───────────────────────────────────────────────────────────────────────────────────────────────
@dataclass(frozen=True)
class Config:
    setting: str = "TidyHouse"
    objects: tuple[str, ...] | None = None
    episodes: int = 8
    subsets: int = 200
    subset_size: int = 80
    bc_rollouts: int = 8
    bc_steps: int = 2000
    ppo_steps: int = 2000
    seed: int = 0
    bc_checkpoint: str | None = None
    ppo_checkpoint: str | None = None
    policies: tuple[str, ...] = POLICIES
    max_steps: int | None = None  # truncate measured episodes and PPO training episodes (smoke tests)


def checkpoints(config: Config, out: Path) -> dict[str, Path | None]:
    """The BC and PPO checkpoints: given, or trained here (reused on a rerun)."""
    found: dict[str, Path | None] = {"expert": None}
    if "bc" in config.policies:
        if config.bc_checkpoint:
            found["bc"] = Path(config.bc_checkpoint)
        else:
            budget = lc.Budget(setting=config.setting, objects=config.objects, rollouts_per_round=config.bc_rollouts,
                               bc_steps=config.bc_steps, seed=config.seed)
            data = out / "data" / f"expert_n{config.bc_rollouts}"
            print(f"BC: {config.bc_rollouts} expert rollouts -> {data}", flush=True)
            r = lc.collect_round(budget, 1, data)
            if not r["successes"]:
                raise RuntimeError(f"no successful expert rollout in {data} to train BC on; raise --bc-rollouts")
            found["bc"], train_s = lc.train_bc_checkpoint(data, out / "bc" / f"n{config.bc_rollouts}_steps{config.bc_steps}",
                                                          config.bc_steps, config.seed)
            print(f"  BC trained on {r['successes']} demos ({r['transitions']} transitions) in {train_s:.0f} s", flush=True)
    if "ppo" in config.policies:
        if config.ppo_checkpoint:
            found["ppo"] = Path(config.ppo_checkpoint)
        else:
            budget = lc.Budget(setting=config.setting, objects=config.objects, ppo_steps=config.ppo_steps, seed=config.seed,
                               max_steps=config.max_steps)
            print(f"PPO from scratch, {config.ppo_steps} interactions", flush=True)
            tag = f"steps{config.ppo_steps}_seed{config.seed}" + (f"_max{config.max_steps}" if config.max_steps else "")
            found["ppo"], train_s = lc.train_ppo_checkpoint(budget, out / "ppo" / tag)
            print(f"  PPO trained in {train_s:.0f} s", flush=True)
    return found


def checkpoint_tag(checkpoint: Path) -> str:
    """A folder name per checkpoint: its run folder's name and a hash of its absolute path (runs often share
    the name `checkpoint`)."""
    path = Path(checkpoint).resolve()
    run_dir = path.parent if path.name == "checkpoint" else path
    return f"{run_dir.name}-{hashlib.sha1(str(path).encode()).hexdigest()[:8]}"


def run(config: Config, out: Path) -> tuple[dict, dict[str, list[np.ndarray]]]:
    from aerobench.envs.platforms import CONTROL_HZ

    out.mkdir(parents=True, exist_ok=True)
    ckpts = checkpoints(config, out)
    rows = {}
    for policy in config.policies:
        tag = (f"{policy}_n{config.episodes}" + ("" if policy == "expert" else f"_{checkpoint_tag(ckpts[policy])}")
               + (f"_max{config.max_steps}" if config.max_steps else ""))
        print(f"{policy}: {config.episodes} Pick episodes on the diversity starts", flush=True)
        rows[policy] = run_policy(config.setting, config.objects, config.episodes, policy, ckpts[policy],
                                  out / "rollouts" / tag, config.max_steps)
    counts = [len(normalized_paths(r)) for r in rows.values() if len(normalized_paths(r)) >= 2]
    # coverage grows with the number of paths: compare every policy on subsets of one common size
    size = min([config.subset_size] + counts)
    summary = {
        "config": asdict(config), "seed": DIVERSITY_SEED, "skill": SKILL, "subset_size": size,
        "checkpoints": {k: str(v) if v else None for k, v in ckpts.items()},
        "policies": {p: measure(r, config.subsets, size, config.seed, 1.0 / CONTROL_HZ) for p, r in rows.items()},
        "spec": SPEC,
    }
    return summary, {p: normalized_paths(r) for p, r in rows.items()}


def plot(summary: dict, paths: dict[str, list[np.ndarray]], out: Path) -> tuple[Path, Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    policies = list(summary["policies"])
    fig, axes = plt.subplots(2, max(len(policies), 3), figsize=(4 * max(len(policies), 3), 7.5))
    for ax, p in zip(axes[0], policies):
        for path in paths[p][:80]:
            ax.plot(path[:, 0], path[:, 1], lw=0.8, alpha=0.6)
        ax.plot([1], [1], "ko", ms=4)
        ax.plot([0], [0], "r*", ms=9)
        ax.set_title(f"{p}: {len(paths[p])} approach paths", fontsize=10)
        ax.set_xlabel("X (normalized)")
        ax.set_ylabel("Z (normalized)")
        ax.set_xlim(-0.5, 1.6)
        ax.set_ylim(-0.5, 1.6)
        ax.set_aspect("equal")
    for ax in axes[0][len(policies):]:
        ax.axis("off")
    for ax, (key, label) in zip(axes[1], (("mean_path_deviation", "deviation from own mean path"),
                                          ("coverage_cells", "occupied 0.05 cells"),
                                          ("direction_entropy_bits", "direction entropy [bits]"))):
        for i, p in enumerate(policies):
            est = summary["policies"][p][key]
            if est is None:
                ax.text(i, 0, "n/a", ha="center", va="bottom", fontsize=8)
                continue
            lo, hi = est["ci95"]
            err = np.clip([[est["mean"] - lo], [hi - est["mean"]]], 0, None)  # rounding when every subset is equal
            ax.bar(i, est["mean"], color=f"C{i}", yerr=err, capsize=4)
        ax.set_xticks(range(len(policies)), policies)
        ax.set_title(f"{label} (subsets of {summary['subset_size']})", fontsize=10)
    fig.suptitle(f"{summary['config']['setting']} Pick, {summary['config']['episodes']} episodes per policy", fontsize=11)
    fig.tight_layout()
    diversity_png = out / "diversity.png"
    fig.savefig(diversity_png, dpi=100)
    plt.close(fig)

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    bottom = np.zeros(len(policies))
    for j, phase in enumerate(PHASES):
        values = np.array([(summary["policies"][p]["time_to_success_s"] or {}).get(phase, 0.0) for p in policies])
        left.bar(policies, values, bottom=bottom, label=phase, color=f"C{j}")
        bottom += values
    for i, p in enumerate(policies):
        if summary["policies"][p]["time_to_success_s"] is None:
            left.text(i, 0, "no success", ha="center", va="bottom", fontsize=8)
    left.set_ylabel("mean time to success [s]")
    left.legend(fontsize=8)
    lengths = [summary["policies"][p]["success_lengths_s"] for p in policies]
    if any(lengths):
        right.hist([np.asarray(x) for x in lengths], bins=20, label=policies)
        right.legend(fontsize=8)
    right.set_xlabel("successful episode length [s]")
    right.set_ylabel("episodes")
    fig.tight_layout()
    efficiency_png = out / "diversity_efficiency.png"
    fig.savefig(efficiency_png, dpi=100)
    plt.close(fig)
    return diversity_png, efficiency_png


def parse_config(argv: list[str] | None = None) -> tuple[Config, Path]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="TidyHouse")
    parser.add_argument("--objects", type=lc._csv, default=None,
                        help=f"comma-separated (default: {','.join(lc.SMALL_OBJECTS)}; with --spec-scale every object)")
    parser.add_argument("--policies", type=lc._csv, default=POLICIES, help="subset of expert,bc,ppo")
    parser.add_argument("--episodes", type=int, default=None, help="Pick episodes per policy (default 8)")
    parser.add_argument("--subsets", type=int, default=200, help="random subsets per estimate")
    parser.add_argument("--subset-size", type=int, default=80, help="paths per subset (capped by the fewest any policy has)")
    parser.add_argument("--bc-checkpoint", default=None, help="a BC checkpoint (default: train one here)")
    parser.add_argument("--ppo-checkpoint", default=None, help="a PPO checkpoint (default: train one here)")
    parser.add_argument("--bc-rollouts", type=int, default=None, help="expert rollouts BC trains on when trained here (8)")
    parser.add_argument("--bc-steps", type=int, default=None, help="BC gradient steps when trained here (2000)")
    parser.add_argument("--ppo-steps", type=int, default=None, help="PPO interactions when trained here (2000)")
    parser.add_argument("--seed", type=int, default=0, help="training and subset-sampling seed")
    parser.add_argument("--max-steps", type=int, default=None, help="truncate measured and PPO training episodes (smoke tests)")
    parser.add_argument("--spec-scale", action="store_true",
                        help="200 subsets of 80 from 256 episodes per policy; BC on 2048 rollouts (8 rounds of 256), "
                             "20k steps; PPO 5M interactions (explicit flags still win)")
    parser.add_argument("--out", default="outputs/bench/diversity")
    args = parser.parse_args(argv)
    base = dict(episodes=256, bc_rollouts=2048, bc_steps=20_000, ppo_steps=5_000_000) if args.spec_scale else {}
    given = {k: getattr(args, k) for k in ("episodes", "bc_rollouts", "bc_steps", "ppo_steps") if getattr(args, k) is not None}
    unknown = [p for p in args.policies if p not in POLICIES]
    if unknown or not args.policies:
        parser.error(f"unknown policies {unknown}; choose from {', '.join(POLICIES)}")
    for name in ("episodes", "subsets", "subset_size", "bc_rollouts", "bc_steps", "ppo_steps"):
        value = {**base, **given}.get(name, getattr(args, name, None))
        if value is not None and value < 1:
            parser.error(f"--{name.replace('_', '-')} must be at least 1, got {value}")
    try:
        from aerobench.envs.tasks import get_setting

        setting = get_setting(args.setting)
        for obj in args.objects or ():
            setting.check_object(obj)
    except ValueError as e:
        parser.error(str(e))
    objects = args.objects or (None if args.spec_scale else lc.SMALL_OBJECTS)
    config = Config(setting=args.setting, objects=objects, subsets=args.subsets, subset_size=args.subset_size,
                    seed=args.seed, bc_checkpoint=args.bc_checkpoint, ppo_checkpoint=args.ppo_checkpoint, max_steps=args.max_steps,
                    policies=tuple(args.policies), **{**base, **given})
    return config, Path(args.out)


def main(argv: list[str] | None = None) -> dict:
    config, out = parse_config(argv)
    started = time.monotonic()
    summary, paths = run(config, out)
    summary["wall_s"] = time.monotonic() - started
    (out / "diversity.json").write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")
    pngs = plot(summary, paths, out)

    def fmt(est):
        return f"{est['mean']:.2f} [{est['ci95'][0]:.2f}, {est['ci95'][1]:.2f}]" if est else "n/a"

    print(f"\n{'policy':8s} {'success':>9s} {'paths':>6s} {'coverage cells':>22s} {'entropy bits':>20s} "
          f"{'mean-path dev':>20s} {'time to success s':>18s}")
    for p, m in summary["policies"].items():
        t = m["time_to_success_s"]
        print(f"{p:8s} {m['successes']:>4d}/{m['episodes']:<4d} {m['approach_paths']:>6d} {fmt(m['coverage_cells']):>22s} "
              f"{fmt(m['direction_entropy_bits']):>20s} {fmt(m['mean_path_deviation']):>20s} "
              + (f"{t['total']:>6.1f} (approach {t['approach']:.1f})" if t else f"{'n/a':>18s}"))
    print(f"subsets of {summary['subset_size']} paths; took {summary['wall_s']:.0f} s; "
          f"wrote {out / 'diversity.json'}, {pngs[0]} and {pngs[1]}")
    return summary


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
