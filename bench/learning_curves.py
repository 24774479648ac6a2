"""The spec's learning-efficiency figure (Sec. "Evaluation of Data Generation Strategies", Fig. learning_curves):
BC held-out success after training on the successful expert rollouts of 1, 2, 4, 8 collection rounds, against PPO's
training success from scratch (400-episode moving average), on a log interaction axis, with the expert's held-out
success as a dotted line.

BC's x is demonstration transitions (frames of the successful expert episodes it trained on); PPO's x is environment
interactions. Every held-out evaluation uses the same seeded starts (`HELD_OUT_SEED`), disjoint from the collection
rounds (round k is generated with seed k). Writes `learning_curves.json` and `learning_curves.png` under `--out`.

The defaults are a small CPU budget (minutes: one object class, rounds 1,2 of 8 rollouts, 2000 BC steps, 2000 PPO
interactions, 4 held-out episodes); `--spec-scale` sets the spec's (rounds 1,2,4,8 of 256 rollouts, every object of
the setting, 20k BC steps, millions of PPO interactions: days on a CPU, so `--ppo-steps` usually overrides it;
`--ppo-steps 0` leaves PPO out). `--skill place` draws the same curve for Place. BC is trained with every seed of
`--bc-seeds` (the spec uses one; two show the spread). Collection rounds and held-out evaluations run in `--workers`
processes (shards). Rerunning the same command continues: each round's dataset, each checkpoint and each
evaluation already in `--out` is reused.

    python bench/learning_curves.py [--rounds 1,2] [--rollouts-per-round 8] [--ppo-steps 2000] [--out DIR]
    python bench/learning_curves.py --spec-scale --ppo-steps 0 --bc-seeds 0,1 --out outputs/bench/learning_curves_spec
    python bench/learning_curves.py --bc-summary learning_curves.json --ppo-run RUN --workers 2 --out DIR

The last form draws the figure from finished parts: a learning curve's summary (expert and BC) and a PPO run trained
apart to millions of interactions, its final checkpoint evaluated on the same held-out starts.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import shutil
import sys
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

import numpy as np  # noqa: E402

HELD_OUT_SEED = 4_000  # evaluation starts, far from the collection rounds (seeds 1..8); seed * 1000003 + i < 2**32
SKILLS = ("pick", "place")  # the spec's learning curves are on Pick; the issue asks for Place too
DONE_FILE = "bench_done.json"  # written after a training run returned: its presence means "reuse"

# The spec's text next to the figure ("Evaluation of Data Generation Strategies").
SPEC = {
    "bc": "On Pick, BC approaches expert success with only 67-81k demonstration transitions",
    "ppo": "PPO requires millions of interactions and remains below the expert in held-out evaluation",
    "protocol": "1, 2, 4 and 8 collection rounds of 256 rollouts; PPO 400-episode moving average; one seed per method",
}


@dataclass(frozen=True)
class Budget:
    setting: str = "TidyHouse"
    skill: str = "pick"
    objects: tuple[str, ...] | None = None  # None: every object of the setting
    rounds: tuple[int, ...] = (1, 2)
    rollouts_per_round: int = 8
    bc_steps: int = 2000
    ppo_steps: int = 2000
    eval_per_object: int = 4
    window: int = 400
    seed: int = 0  # PPO's seed
    bc_seeds: tuple[int, ...] = (0,)
    workers: int = 1  # collection and evaluation processes
    max_steps: int | None = None  # truncate held-out and PPO training episodes (smoke tests; collection runs in full)
    transition_budget: int | None = None  # one more BC point: the leading demos of all rounds within this many frames
    action_noise: float = 0.0  # DART noise on the collection rounds' executed flight commands (aerobench.rollout.noise)
    ppo_recipe: str = "spec"  # PPO_RECIPES

    def __post_init__(self):
        if self.skill not in SKILLS:
            raise ValueError(f"--skill must be one of {', '.join(SKILLS)}, got {self.skill!r}")
        if not self.bc_seeds or self.workers < 1 or self.ppo_steps < 0:
            raise ValueError("--bc-seeds needs at least one seed, --workers at least 1, --ppo-steps at least 0")
        if not self.rounds or any(r < 1 for r in self.rounds) or list(self.rounds) != sorted(set(self.rounds)):
            raise ValueError(f"--rounds must be increasing positive integers like 1,2,4,8; got {self.rounds}")
        from aerobench.rollout.noise import check_action_noise

        check_action_noise(self.action_noise)
        if self.transition_budget is not None and self.transition_budget < 1:
            raise ValueError(f"--transition-budget must be a positive integer, got {self.transition_budget}")
        if self.ppo_recipe not in PPO_RECIPES:
            raise ValueError(f"--ppo-recipe must be one of {', '.join(PPO_RECIPES)}, got {self.ppo_recipe!r}")
        for name in ("rollouts_per_round", "bc_steps", "eval_per_object", "window"):
            if getattr(self, name) < 1:
                raise ValueError(f"--{name.replace('_', '-')} must be at least 1, got {getattr(self, name)}")


# PPO from scratch. "spec": the trainer's defaults, the spec's reference configuration (64-step windows, gamma 0.97,
# clip 0.2), which the spec runs on a GPU batch of envs. "cpu": what learned on two CPU envs (docs/experiments.md, "PPO
# from scratch on a CPU"): 1024-step windows (2,048 samples per update, the batch of 32 GPU envs at 64 steps), the
# dense reward, the finger state among the inputs, and a learning rate constant until 1.5M interactions (the two seeds
# that lifted found it at 830k and 968k), then falling linearly to 0 at the budget's end: at a constant rate success
# peaked near 2.5M and declined, annealed after the lift it kept rising (docs/experiments.md, "Constant until 1.5M").
# A run that lifts after 1.5M gets too little rate to build on it (seed 2: the lift at 1.87M, 6/180 at 4M).
# `train ppo --lr-decay-at-success` starts the decay from training success instead (seed 2: 18/180 at 5.12M).
PPO_RECIPES = {
    "spec": {},
    "cpu": dict(reward="dense", num_steps=1024, num_minibatches=32, update_epochs=4,
                state_fields=("finger_position", "finger_velocity"), lr_decay_start=1_500_000),
}
SMALL_OBJECTS = ("master_chef_can",)  # the small budget's one object class (the spec scale uses all)
SPEC_SCALE = dict(rounds=(1, 2, 4, 8), rollouts_per_round=256, bc_steps=20_000, ppo_steps=5_000_000, eval_per_object=50)


def ppo_recipe(name: str, total_steps: int) -> dict:
    """The PPOConfig options of recipe `name` for a budget of `total_steps`: a recipe's `lr_decay_start` anneals the
    rate from there to 0 at the budget's end (a budget that ends before it keeps the rate constant)."""
    recipe = dict(PPO_RECIPES[name])
    start = recipe.pop("lr_decay_start", 0)
    if start and total_steps > start:
        recipe.update(lr_decay_start=start, lr_decay_steps=total_steps)
    return recipe


# ── collection ───────────────────────────────────────────────────────────────────────────────────────────────────
def collect_round(budget: Budget, k: int, root: Path) -> dict:
    """Collection round k: `rollouts_per_round` state-only expert rollouts of the skill (seed k), successes kept;
    `workers` shard processes write into the same dataset folder, which is merged when they are all done."""
    from aerobench.export.sink import merge_parts
    from aerobench.rollout.runner import RolloutSpec

    spec = RolloutSpec(setting=budget.setting, skills=(budget.skill,), episodes=budget.rollouts_per_round,
                       objects=budget.objects, seed=k, policy="expert", record_cameras=False,
                       action_noise=budget.action_noise)
    started = time.monotonic()
    run_done = sum(in_workers(_collect_shard, [(spec, (i, budget.workers), root) for i in range(budget.workers)]))
    if (root / ".aerobench" / "parts").is_dir():
        merge_parts(root)
    elapsed = time.monotonic() - started
    records = [json.loads(line) for line in (root / ".aerobench" / "records.jsonl").read_text().splitlines() if line]
    return {
        "round": k, "episodes": len(records), "successes": sum(r["outcome"] == "S" for r in records),
        "transitions": transitions(root), "run_now": run_done, "run_s": elapsed,
    }


def _collect_shard(spec, shard: tuple[int, int], root: Path) -> int:
    from dataclasses import replace

    from aerobench.export import DatasetSink
    from aerobench.rollout.runner import RolloutRunner

    spec = replace(spec, shard=shard)
    sink = DatasetSink(root, {**spec.as_dict(), "keep": "success"}, keep=lambda r: r.outcome == "S")
    progress = RolloutRunner(spec, sink).run()
    sink.close(merge=False)
    return progress.run_done


def in_workers(fn, calls: list[tuple]) -> list:
    """`fn(*args)` for every tuple of `calls`, each in its own spawned process when there are several (physx_cpu
    runs one env per process), with one torch thread each; results in call order."""
    if len(calls) == 1:
        return [_one_thread(fn, *calls[0])]
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(len(calls), mp_context=multiprocessing.get_context("spawn")) as pool:
        return [f.result() for f in [pool.submit(_one_thread, fn, *args) for args in calls]]


def _one_thread(fn, *args):
    from aerobench.threads import torch_threads

    with torch_threads(1):
        return fn(*args)


def transitions(root: Path) -> int:
    """Frames in the LeRobot dataset at root (0 when no episode was kept)."""
    info = root / "meta" / "info.json"
    return int(json.loads(info.read_text())["total_frames"]) if info.is_file() else 0


def cumulative_dataset(rounds: list[Path], dst: Path) -> Path | None:
    """One dataset with the kept episodes of `rounds`, in order (`aerobench dataset join`). Built once into a
    temporary folder, then renamed into place."""
    from aerobench.export.tools import join_datasets

    sources = [r for r in rounds if (r / "meta" / "info.json").is_file()]
    if not sources:
        return None
    if len(sources) == 1:
        return sources[0]
    if (dst / DONE_FILE).is_file():
        return dst
    work = dst.with_name(dst.name + ".tmp")
    shutil.rmtree(work, ignore_errors=True)
    join_datasets(sources, work)
    (work / DONE_FILE).write_text(json.dumps({"sources": [str(s) for s in sources]}) + "\n")
    shutil.rmtree(dst, ignore_errors=True)
    work.rename(dst)
    return dst


# ── training (the trainers live in aerobench.train) ──────────────────────────────────────────────────────────────
def _done(out: Path) -> Path | None:
    marker = out / DONE_FILE
    return Path(json.loads(marker.read_text())["checkpoint"]) if marker.is_file() else None


def _mark_done(out: Path, checkpoint: Path, seconds: float) -> None:
    (out / DONE_FILE).write_text(json.dumps({"checkpoint": str(checkpoint), "train_s": seconds}) + "\n")


def train_bc_checkpoint(dataset: Path, out: Path, steps: int, seed: int,
                        max_transitions: int | None = None) -> tuple[Path, float]:
    """A state-only BC checkpoint trained on `dataset`, or on its leading demos within `max_transitions` frames
    (reused when `out` holds a finished one)."""
    if (ckpt := _done(out)) is not None:
        return ckpt, json.loads((out / DONE_FILE).read_text())["train_s"]
    from aerobench.train.bc import BCConfig, train_bc

    started = time.monotonic()  # an interrupted run resumes from its last checkpoint (the time is this run's)
    ckpt = Path(train_bc(BCConfig(dataset=str(dataset), out=str(out), steps=steps, seed=seed, images=False,
                                  progress=False, max_transitions=max_transitions)))
    elapsed = time.monotonic() - started
    _mark_done(out, ckpt, elapsed)
    return ckpt, elapsed


def train_ppo_checkpoint(budget: Budget, out: Path) -> tuple[Path, float]:
    """PPO from scratch on the setting's skill, one env per `--workers` (rollout worker processes; reused when `out`
    holds a finished run, resumed when it holds an interrupted one)."""
    if (ckpt := _done(out)) is not None:
        return ckpt, json.loads((out / DONE_FILE).read_text())["train_s"]
    from aerobench.train.ppo import PPOConfig, train_ppo

    started = time.monotonic()  # an interrupted run resumes from its last checkpoint (the time is this run's)
    ckpt = Path(train_ppo(PPOConfig(setting=budget.setting, skill=budget.skill, objects=budget.objects, out=str(out),
                                    total_steps=budget.ppo_steps, seed=budget.seed, init_bc=None,
                                    num_envs=max(1, budget.workers), max_episode_steps=budget.max_steps,
                                    progress=False, **ppo_recipe(budget.ppo_recipe, budget.ppo_steps))))
    elapsed = time.monotonic() - started
    _mark_done(out, ckpt, elapsed)
    return ckpt, elapsed


def ppo_training_episodes(out: Path) -> list[dict]:
    """PPO's `train_episodes.jsonl` rows (global_step, episode, success, return, length, and since 2026-11-30 outcome
    and peak_potential), in order."""
    from aerobench.rollout.records import read_records

    path = out / "train_episodes.jsonl"
    if not path.is_file():
        raise ValueError(f"{path} is missing: the PPO trainer writes one line per finished training episode there")
    return sorted(read_records(path), key=lambda r: r["global_step"])  # a running run's torn last line is ignored


def moving_average(values: np.ndarray, window: int) -> np.ndarray:
    """Trailing mean over the last `window` values (fewer at the start)."""
    values = np.asarray(values, float)
    csum = np.concatenate([[0.0], np.cumsum(values)])
    idx = np.arange(1, len(values) + 1)
    lo = np.maximum(idx - window, 0)
    return (csum[idx] - csum[lo]) / (idx - lo)


# ── held-out evaluation ──────────────────────────────────────────────────────────────────────────────────────────
def held_out(budget: Budget, policy: str, checkpoint: Path | None, out: Path) -> dict:
    """Pooled held-out Pick success of `policy` on the same seeded starts for every policy (resumes in `out`)."""
    from aerobench.eval.evaluate import EvalConfig, evaluate
    from aerobench.eval.stats import wilson_interval

    config = EvalConfig(policy=policy, setting=budget.setting, skills=(budget.skill,), objects=budget.objects,
                        episodes_per_object=budget.eval_per_object, checkpoint=str(checkpoint) if checkpoint else None,
                        seed=HELD_OUT_SEED, max_steps=budget.max_steps, workers=budget.workers)
    started = time.monotonic()
    results = evaluate(config, out)
    n = sum(c["n"] for c in results["cells"])
    k = sum(c["successes"] for c in results["cells"])
    lo, hi = wilson_interval(k, n)
    per_object = {c["object"]: [c["successes"], c["n"]] for c in results["cells"]}
    return {"success": k / n if n else 0.0, "successes": k, "n": n, "wilson95": [lo, hi], "per_object": per_object,
            "eval_s": time.monotonic() - started, "results": str(out / "results.json")}


def ppo_result(budget: Budget, ppo_dir: Path, ckpt: Path, train_s: float | None, eval_dir: Path) -> dict:
    """A PPO run's curve (`budget.window`-episode moving average of training success), its held-out success and the
    training options that tell one recipe from another."""
    from aerobench.policies.learned import read_config

    train = read_config(ckpt)["train"]
    episodes = ppo_training_episodes(ppo_dir)
    steps = np.array([e["global_step"] for e in episodes], float)
    success = np.array([float(bool(e["success"])) for e in episodes])
    ma = moving_average(success, budget.window)
    keep = np.unique(np.linspace(0, len(ma) - 1, min(len(ma), 1000)).astype(int)) if len(ma) else np.zeros(0, int)
    result = {
        "checkpoint": str(ckpt), "train_s": train_s, "episodes": len(episodes), "successes": int(success.sum()),
        "interactions": int(steps[-1]) if len(steps) else 0,
        "interactions_per_s": float(steps[-1] / train_s) if len(steps) and train_s else None,
        "final_moving_average": float(ma[-1]) if len(ma) else None,
        "curve": {"global_step": steps[keep].astype(int).tolist(), "success_moving_average": ma[keep].tolist()},
        "held_out": held_out(budget, "ppo", ckpt, eval_dir),
        "train_config": {k: train.get(k) for k in ("reward", "num_steps", "num_envs", "num_minibatches",
                                                   "update_epochs", "state_fields", "seed", "gamma", "learning_rate",
                                                   "lr_decay_steps", "lr_decay_start")},
    }
    print(f"  PPO: {result['episodes']} training episodes, {result['successes']} successful, final moving average "
          f"{result['final_moving_average']}; {result['interactions_per_s'] or 0:.0f} interactions/s; held-out "
          f"{result['held_out']['successes']}/{result['held_out']['n']}", flush=True)
    return result


def logged_train_seconds(ppo_dir: Path) -> float | None:
    """A run's training time from its logged per-window throughput (`charts/SPS`, interactions per second of each
    rollout + update window): the sum of each window's interactions over its rate. None without the log."""
    from aerobench.train.common import read_scalars

    seconds, previous = 0.0, 0
    for step, rate in read_scalars(ppo_dir, "charts/SPS"):
        if rate > 0:
            seconds, previous = seconds + (step - previous) / rate, step
    return seconds or None


def with_ppo_run(summary_file: Path, ppo_dir: Path, out: Path, workers: int) -> dict:
    """The figure from finished parts: the expert and BC rows of a learning-curves summary (`--bc-summary`) and a PPO
    run trained apart (`--ppo-run`, e.g. `aerobench train ppo` to millions of interactions), whose final checkpoint is
    evaluated on the summary's held-out starts (the same seed and episodes per object as BC and the expert)."""
    from aerobench.policies.learned import read_config

    try:
        summary = json.loads(summary_file.read_text())
        saved = summary["budget"]
    except (OSError, json.JSONDecodeError, KeyError) as e:
        raise ValueError(f"--bc-summary {summary_file} is not a learning_curves.json ({e}); pass the JSON this "
                         f"script writes (e.g. docs/results/learning_curves/TidyHouse_pick_v3.json)") from None
    if summary.get("held_out_seed") != HELD_OUT_SEED:
        raise ValueError(f"--bc-summary {summary_file} was evaluated on seed {summary.get('held_out_seed')}, this "
                         f"script evaluates on {HELD_OUT_SEED}; re-run its learning curve with this script")
    known = {f.name for f in fields(Budget)}
    budget = Budget(**{**{k: tuple(v) if isinstance(v, list) else v for k, v in saved.items() if k in known},
                       "workers": workers, "ppo_steps": 0})
    ckpt = ppo_dir / "checkpoint"
    if not (ckpt / "config.json").is_file():
        raise ValueError(f"--ppo-run {ppo_dir} holds no checkpoint/config.json; pass the --out folder of an "
                         f"`aerobench train ppo` run")
    config = read_config(ckpt)
    train = config["train"]
    theirs = (train["setting"], train["skill"], tuple(train["objects"]) if train.get("objects") else None)
    if config["algorithm"] != "ppo" or theirs != (budget.setting, budget.skill, budget.objects):
        raise ValueError(f"--ppo-run {ppo_dir} is a {config['algorithm']} run of {theirs}, the summary's curve is "
                         f"{(budget.setting, budget.skill, budget.objects)}; pass a PPO run of the same setting, "
                         f"skill and objects")
    summary["ppo"] = ppo_result(budget, ppo_dir, ckpt, logged_train_seconds(ppo_dir),
                                out / "eval" / f"ppo_{ppo_dir.name}_e{budget.eval_per_object}")
    summary["budget"] = {**saved, "ppo_steps": summary["ppo"]["interactions"]}
    summary["sources"] = {"bc_summary": str(summary_file), "ppo_run": str(ppo_dir)}
    return summary


# ── the experiment ───────────────────────────────────────────────────────────────────────────────────────────────
def run(budget: Budget, out: Path) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    tag = f"n{budget.rollouts_per_round}" + (f"_max{budget.max_steps}" if budget.max_steps else "")
    summary: dict = {"budget": asdict(budget), "held_out_seed": HELD_OUT_SEED, "skill": budget.skill, "spec": SPEC}
    evals = f"e{budget.eval_per_object}"

    print(f"expert held-out ({budget.eval_per_object} per object) ...", flush=True)
    summary["expert"] = held_out(budget, "expert", None, out / "eval" / f"expert_{tag}_{evals}")
    print(f"  expert held-out success {summary['expert']['successes']}/{summary['expert']['n']}", flush=True)

    rounds, round_roots = [], []
    for k in range(1, max(budget.rounds) + 1):
        root = out / "data" / tag / f"round_{k:02d}"
        print(f"collection round {k}: {budget.rollouts_per_round} expert rollouts -> {root}", flush=True)
        rounds.append(collect_round(budget, k, root))
        round_roots.append(root)
        r = rounds[-1]
        ran = f"{r['run_now']} run now at {60 * r['run_now'] / r['run_s']:.1f} episodes/min" if r["run_now"] else "reused"
        print(f"  {r['successes']}/{r['episodes']} successful, {r['transitions']} transitions; {ran}", flush=True)
    summary["rounds"] = rounds

    summary["bc"] = []
    for n_rounds in budget.rounds:
        dataset = cumulative_dataset(round_roots[:n_rounds], out / "data" / tag / f"rounds_1-{n_rounds}")
        row: dict = {"rounds": n_rounds, "rollouts": n_rounds * budget.rollouts_per_round,
                     "demos": sum(r["successes"] for r in rounds[:n_rounds]),
                     "transitions": sum(r["transitions"] for r in rounds[:n_rounds])}
        summary["bc"].append(bc_row(budget, out, row, dataset, f"{tag}_rounds{n_rounds}"))
    if budget.transition_budget:
        # The data budget as its own point: the demos of every round in collection order, up to the budget's frames.
        n_rounds, cap = max(budget.rounds), budget.transition_budget
        dataset = cumulative_dataset(round_roots[:n_rounds], out / "data" / tag / f"rounds_1-{n_rounds}")
        row = {"rounds": n_rounds, "rollouts": n_rounds * budget.rollouts_per_round, "transition_budget": cap}
        summary["bc"].append(bc_row(budget, out, row, dataset, f"{tag}_rounds{n_rounds}_cap{cap}", cap))

    if budget.ppo_steps == 0:
        summary["ppo"] = None
        return summary

    ppo_dir = out / "ppo" / (f"steps{budget.ppo_steps}_seed{budget.seed}" + (f"_max{budget.max_steps}" if budget.max_steps else "")
                             + (f"_{budget.ppo_recipe}" if budget.ppo_recipe != "spec" else ""))
    print(f"PPO from scratch, {budget.ppo_steps} interactions -> {ppo_dir}", flush=True)
    ckpt, train_s = train_ppo_checkpoint(budget, ppo_dir)
    summary["ppo"] = ppo_result(budget, ppo_dir, ckpt, train_s, out / "eval" / f"ppo_{ppo_dir.name}_{evals}")
    return summary


def bc_row(budget: Budget, out: Path, row: dict, dataset: Path | None, name: str, cap: int | None = None) -> dict:
    """BC trained on `dataset` (its leading demos within `cap` frames when given) with every training seed, each
    evaluated held out; the row pools the seeds' episodes (each seed's own numbers stay in "seeds")."""
    from aerobench.eval.stats import wilson_interval
    from aerobench.policies.learned import read_config

    label = f"{row['rounds']} round(s)" + (f" capped at {cap} transitions" if cap else "")
    if dataset is None:
        print(f"BC after {label}: no successful expert rollout to train on", flush=True)
        return {**row, "held_out": None, "train_s": None, "checkpoint": None, "seeds": []}
    row["seeds"] = []
    for seed in budget.bc_seeds:
        ckpt_dir = out / "bc" / (f"{name}_steps{budget.bc_steps}" + (f"_seed{seed}" if seed else ""))
        ckpt, train_s = train_bc_checkpoint(dataset, ckpt_dir, budget.bc_steps, seed, cap)
        if cap:  # what the budget admitted, as the trainer counted it
            data = read_config(ckpt)["data"]
            row.update(demos=data["episodes"], transitions=data["frames"])
        h = held_out(budget, "bc", ckpt, out / "eval" / f"{ckpt_dir.name}_e{budget.eval_per_object}")
        row["seeds"].append({"seed": seed, "checkpoint": str(ckpt), "train_s": train_s, "held_out": h})
        print(f"BC after {label} ({row['transitions']} transitions, seed {seed}, {budget.bc_steps} "
              f"steps in {train_s:.0f} s): held-out {h['successes']}/{h['n']}", flush=True)
    k, n = sum(r["held_out"]["successes"] for r in row["seeds"]), sum(r["held_out"]["n"] for r in row["seeds"])
    row.update(checkpoint=row["seeds"][0]["checkpoint"], train_s=row["seeds"][0]["train_s"],
               held_out={"success": k / n if n else 0.0, "successes": k, "n": n,
                         "wilson95": list(wilson_interval(k, n)), "pooled_seeds": list(budget.bc_seeds)})
    return row


def plot(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.6))
    bc = sorted((r for r in summary["bc"] if r["held_out"] and r["transitions"] > 0), key=lambda r: r["transitions"])
    if bc:
        x = np.array([r["transitions"] for r in bc], float)
        y = np.array([r["held_out"]["success"] for r in bc])
        err = np.array([[r["held_out"]["success"] - r["held_out"]["wilson95"][0],
                         r["held_out"]["wilson95"][1] - r["held_out"]["success"]] for r in bc]).T.clip(0)
        seeds = len(bc[0].get("seeds") or [None])
        ax.errorbar(x, y, yerr=err, fmt="o-", color="C0", capsize=3,
                    label=f"BC held-out (demonstration transitions; {seeds} training seed{'s' * (seeds > 1)} pooled)")
        if seeds > 1:
            for r in bc:
                ys = [s["held_out"]["success"] for s in r["seeds"]]
                ax.plot([r["transitions"]] * len(ys), ys, "_", color="C0", ms=10, mew=1.5)
        for r, xi, yi in zip(bc, x, y):
            ax.annotate(f"{r['rounds']}r" + (f" cap {r['transition_budget'] / 1000:g}k" if r.get("transition_budget") else ""),
                        (xi, yi), textcoords="offset points", xytext=(4, 4), fontsize=8)
    curve = summary["ppo"]["curve"] if summary["ppo"] else {"global_step": []}
    if curve["global_step"]:
        t = summary["ppo"].get("train_config") or {}
        recipe = (f"\n{t['reward']} reward, {t['num_steps']}-step windows x {t['num_envs']} envs"
                  + (f", + {', '.join(t['state_fields'])}" if t.get("state_fields") else "")
                  + (f", lr to 0 at {t['lr_decay_steps'] / 1e6:g}M" if t.get("lr_decay_steps") else "")
                  + (f" from {t['lr_decay_start'] / 1e6:g}M" if t.get("lr_decay_start") else "")) if t else ""
        ax.plot(np.maximum(curve["global_step"], 1), curve["success_moving_average"], color="C1",
                label=f"PPO training success ({summary['budget']['window']}-episode moving average){recipe}")
        h = summary["ppo"]["held_out"]
        ax.plot([max(summary["ppo"]["interactions"], 1)], [h["success"]], "s", color="C1", mfc="none",
                label="PPO held-out")
    ax.axhline(summary["expert"]["success"], color="k", ls=":", label="expert held-out")
    ax.set_xscale("log")
    ax.set_ylim(-0.03, 1.03)
    ax.set_xlabel("demonstration transitions (BC) / environment interactions (PPO)")
    ax.set_ylabel(f"{summary['budget']['setting']} {summary['skill'].capitalize()} success")
    b = summary["budget"]
    ax.set_title(f"{b['rollouts_per_round']} rollouts/round, rounds {','.join(map(str, b['rounds']))}, "
                 f"BC {b['bc_steps']} steps" + (f", PPO {b['ppo_steps']} interactions" if b["ppo_steps"] else "")
                 + f"\nheld-out {b['eval_per_object']} episodes per object", fontsize=9)
    ax.legend(fontsize=7, loc="center left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _ints(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers like 1,2,4,8; got {text!r}") from None


def _csv(text: str) -> tuple[str, ...]:
    return tuple(x.strip() for x in text.split(",") if x.strip())


def parse_budget(argv: list[str] | None = None) -> tuple[Budget, Path, tuple[Path, Path] | None]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="TidyHouse")
    parser.add_argument("--objects", type=_csv, default=None,
                        help=f"comma-separated (default: {','.join(SMALL_OBJECTS)}; with --spec-scale every object)")
    parser.add_argument("--rounds", type=_ints, default=None, help="BC after this many collection rounds (default 1,2)")
    parser.add_argument("--rollouts-per-round", type=int, default=None, help="expert rollouts per round (default 8)")
    parser.add_argument("--bc-steps", type=int, default=None, help="BC gradient steps per checkpoint (default 2000)")
    parser.add_argument("--ppo-steps", type=int, default=None, help="PPO environment interactions (default 2000)")
    parser.add_argument("--eval-per-object", type=int, default=None, help="held-out episodes per object (default 4)")
    parser.add_argument("--window", type=int, default=400, help="PPO moving-average window in episodes")
    parser.add_argument("--skill", default="pick", help="pick (the spec's figure) or place")
    parser.add_argument("--seed", type=int, default=0, help="PPO's training seed")
    parser.add_argument("--bc-seeds", type=_ints, default=(0,), help="BC training seeds (default 0)")
    parser.add_argument("--workers", type=int, default=1, help="collection and evaluation processes and PPO rollout workers (e.g. the cores)")
    parser.add_argument("--max-steps", type=int, default=None, help="truncate held-out and PPO training episodes (smoke tests)")
    parser.add_argument("--transition-budget", type=int, default=None,
                        help="also train BC on the leading demos of all rounds (collection order) within this many "
                             "transitions, e.g. 81000 for the spec's '67-81k'")
    parser.add_argument("--action-noise", type=float, default=0.0,
                        help="collect the rounds with DART noise of this std on the executed flight commands (the "
                             "demonstrations keep the expert's own actions); held-out evaluations run without noise")
    parser.add_argument("--ppo-recipe", default="spec", choices=tuple(PPO_RECIPES),
                        help="PPO from scratch: spec (the spec's reference configuration, the trainer's defaults) or "
                             "cpu (1024-step windows, the dense reward, finger state, the rate annealed after 1.5M: what "
                             "learned on two CPU envs)")
    parser.add_argument("--spec-scale", action="store_true",
                        help="the spec's budget: rounds 1,2,4,8 of 256 rollouts, 20k BC steps, 5M PPO interactions, "
                             "50 held-out episodes per object (explicit flags still win)")
    parser.add_argument("--bc-summary", type=Path, default=None,
                        help="with --ppo-run: draw the figure from this finished learning_curves.json (its expert and "
                             "BC rows, budget and held-out starts) instead of running them")
    parser.add_argument("--ppo-run", type=Path, default=None,
                        help="with --bc-summary: the --out folder of a PPO run trained apart (e.g. `aerobench train "
                             "ppo` to millions of interactions); its checkpoint is evaluated on the summary's starts")
    parser.add_argument("--out", default="outputs/bench/learning_curves")
    args = parser.parse_args(argv)
    if (args.bc_summary is None) != (args.ppo_run is None):
        parser.error("--bc-summary and --ppo-run go together: a finished learning_curves.json and a PPO run folder")
    base = SPEC_SCALE if args.spec_scale else {}
    given = {k: getattr(args, k) for k in ("rounds", "rollouts_per_round", "bc_steps", "ppo_steps", "eval_per_object")
             if getattr(args, k) is not None}
    try:
        from aerobench.envs.tasks import get_setting

        setting = get_setting(args.setting)
        for obj in args.objects or ():
            setting.check_object(obj)
        objects = args.objects or (None if args.spec_scale else SMALL_OBJECTS)
        budget = Budget(setting=args.setting, skill=args.skill, objects=objects, window=args.window, seed=args.seed,
                        bc_seeds=args.bc_seeds, workers=args.workers, max_steps=args.max_steps,
                        transition_budget=args.transition_budget, action_noise=args.action_noise,
                        ppo_recipe=args.ppo_recipe,
                        **{**base, **given})
    except ValueError as e:
        parser.error(str(e))
    return budget, Path(args.out), ((args.bc_summary, args.ppo_run) if args.ppo_run else None)


def main(argv: list[str] | None = None) -> dict:
    budget, out, finished = parse_budget(argv)
    started = time.monotonic()
    if finished:
        out.mkdir(parents=True, exist_ok=True)
        try:
            summary = with_ppo_run(*finished, out, budget.workers)
        except ValueError as e:
            sys.exit(f"error: {e}")
    else:
        summary = run(budget, out)
    summary["wall_s"] = time.monotonic() - started
    (out / "learning_curves.json").write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")
    plot(summary, out / "learning_curves.png")
    e = summary["expert"]
    print(f"\nexpert held-out {100 * e['success']:.1f}% ({e['successes']}/{e['n']})")
    for r in summary["bc"]:
        h = r["held_out"]
        per_seed = ", ".join(f"seed {s['seed']} {s['held_out']['successes']}/{s['held_out']['n']}" for s in r["seeds"])
        cap = f" capped at {r['transition_budget']}" if r.get("transition_budget") else ""
        print(f"BC {r['rounds']} round(s){cap}: {r.get('transitions', 0):>7d} transitions -> "
              + (f"{100 * h['success']:.1f}% ({h['successes']}/{h['n']}; {per_seed})" if h else "no data"))
    p = summary["ppo"]
    if p:
        ratio = (p["interactions"] / max(summary["bc"][-1]["transitions"], 1)) if summary["bc"] else math.nan
        print(f"PPO {p['interactions']} interactions -> training moving average {p['final_moving_average']}, held-out "
              f"{100 * p['held_out']['success']:.1f}%; PPO interactions / BC transitions (largest) = {ratio:.2f}")
    print(f"took {summary['wall_s']:.0f} s; wrote {out / 'learning_curves.json'} and {out / 'learning_curves.png'}")
    return summary


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
