"""Which inputs and which gripper head let BC learn a skill (Pick by default): closed-loop, held-out success of BC variants that differ in
one design choice each, with two training seeds (docs/experiments.md, "Why BC learned nothing").

Every variant trains `aerobench.train.bc` on the same demonstrations (`--dataset`, an aerobench export with the
task state; without one, `--demos` state-only expert episodes of `--objects` are generated first, with seed 0) for
the same steps and is scored by `aerobench.eval` on the same held-out starts (`--eval-seed`, a seed the
demonstrations were not generated with), optionally also on starts of its own training data (`--train-seed`).
Writes `bc_inputs.json` (every number) under `--out`; rerunning the same command reuses finished checkpoints and
evaluations. With no arguments it is a small CPU budget (`make bench`: 32 demonstrations of the master chef can,
the shipped design against no heading error, 3000 steps, 5 held-out episodes per training seed).

    python bench/bc_inputs.py                                              # small budget
    python bench/bc_inputs.py --dataset outputs/data/pick_mcc --variants default,history_1,finger_inputs \
        --steps 20000 --episodes 20 --out outputs/bench/bc_inputs          # docs/experiments.md
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

from aerobench.policies.inputs import ALL_TASK_FIELDS, FINGER_FIELDS  # noqa: E402

GRIPPER_TASK_FIELDS = tuple(f for f in ALL_TASK_FIELDS if f != "arm_position")


def _without(*fields: str) -> tuple[str, ...]:
    return tuple(f for f in GRIPPER_TASK_FIELDS if f not in fields)


# One design choice each. "default" is the shipped BC (BCConfig's defaults: the whole task state, no proprio field,
# a binary gripper head, 3 frames); "history_1" drops the history, and the single-factor ablations below change one
# more thing against "history_1" (they were measured before the history became the default). Values are BCConfig
# fields.
MARKOV = {"history": 1}
VARIANTS: dict[str, dict] = {
    "default": {},
    "history_1": MARKOV,
    "history_5": {"history": 5},
    "finger_inputs": {**MARKOV, "state_fields": FINGER_FIELDS},  # + proprio finger position and velocity
    "regressed_gripper": {**MARKOV, "gripper": "continuous"},  # the gripper regressed with the flight dims (MSE)
    "finger_inputs_regressed_gripper": {**MARKOV, "state_fields": FINGER_FIELDS, "gripper": "continuous"},
    "no_heading_error": {**MARKOV, "task_fields": _without("heading_error")},
    "no_grasp_flag": {**MARKOV, "task_fields": _without("is_grasp_confirmed")},
    "absolute_position": {**MARKOV, "state_fields": ("position",)},  # + the airframe's absolute position
    "world_frame_only": {**MARKOV, "task_fields": _without("goal_pos_body")},
}


def train(name: str, dataset: Path, out: Path, steps: int, seed: int) -> tuple[Path, float]:
    from aerobench.train.bc import BCConfig, train_bc

    done = out / "bench_done.json"
    if done.is_file():
        row = json.loads(done.read_text())
        return Path(row["checkpoint"]), row["train_s"]
    started = time.monotonic()
    ckpt = train_bc(BCConfig(dataset=str(dataset), out=str(out), steps=steps, seed=seed, progress=False,
                             **VARIANTS[name]))
    elapsed = time.monotonic() - started
    done.write_text(json.dumps({"checkpoint": str(ckpt), "train_s": elapsed}) + "\n")
    return ckpt, elapsed


def score(checkpoint: Path, setting: str, skill: str, objects: tuple[str, ...] | None, episodes: int, seed: int,
          workers: int, out: Path) -> dict:
    from aerobench.eval.evaluate import EvalConfig, evaluate
    from aerobench.eval.results import over_all_cells

    results = evaluate(EvalConfig(policy="bc", setting=setting, skills=(skill,), objects=objects,
                                  episodes_per_object=episodes, checkpoint=str(checkpoint), seed=seed,
                                  workers=workers), out)
    pooled = over_all_cells(results)
    return {"successes": pooled["successes"], "n": pooled["n"], "modes": pooled["modes"],
            "seen_in_training": results["provenance"]["seen_in_training"]}


def generate(args, objects: tuple[str, ...] | None, root: Path) -> Path:
    """`args.demos` state-only expert episodes (seed 0, successes kept) in `args.workers` processes."""
    sys.path.insert(0, str(Path(__file__).parent))
    import learning_curves as lc

    budget = lc.Budget(setting=args.setting, skill=args.skill, objects=objects, rollouts_per_round=args.demos,
                       workers=args.workers)
    print(f"{args.demos} expert {args.skill} demonstrations -> {root}", flush=True)
    r = lc.collect_round(budget, 0, root)
    print(f"  {r['successes']}/{r['episodes']} successful, {r['transitions']} transitions", flush=True)
    return root


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default=None, help="aerobench export of expert demonstrations of --skill "
                        "(default: generate --demos episodes into OUT/data)")
    parser.add_argument("--demos", type=int, default=32, help="expert episodes to generate when no --dataset is given")
    parser.add_argument("--setting", default="TidyHouse")
    parser.add_argument("--skill", default="pick", help="the skill the demonstrations show (pick or place)")
    parser.add_argument("--objects", default="master_chef_can", help="comma-separated objects of the evaluation (and "
                        "of generated demonstrations); 'all': the setting's")
    parser.add_argument("--variants", default="default,no_heading_error", help=f"comma-separated, of: {', '.join(VARIANTS)}")
    parser.add_argument("--seeds", default="0,1", help="training seeds")
    parser.add_argument("--steps", type=int, default=3000, help="BC gradient steps")
    parser.add_argument("--episodes", type=int, default=5, help="held-out episodes per object")
    parser.add_argument("--eval-seed", type=int, default=1, help="held-out starts (not the data's generation seed)")
    parser.add_argument("--train-seed", type=int, default=None, help="also score on starts of this seed (the data's)")
    parser.add_argument("--train-episodes", type=int, default=10, help="episodes per object on the training starts")
    parser.add_argument("--workers", type=int, default=2, help="evaluation worker processes")
    parser.add_argument("--out", default="outputs/bench/bc_inputs")
    args = parser.parse_args(argv)
    names = [v for v in args.variants.split(",") if v]
    unknown = [v for v in names if v not in VARIANTS]
    if unknown:
        parser.error(f"unknown variants {unknown}; valid: {', '.join(VARIANTS)}")
    objects = None if args.objects == "all" else tuple(args.objects.split(","))
    seeds = [int(s) for s in args.seeds.split(",")]
    out = Path(args.out)
    dataset = Path(args.dataset) if args.dataset else generate(args, objects, out / "data" / f"{args.skill}_{args.demos}")
    summary = {"dataset": str(dataset), "skill": args.skill, "steps": args.steps, "eval_seed": args.eval_seed, "objects": objects,
               "episodes_per_object": args.episodes, "variants": {}}
    for name in names:
        rows = []
        for seed in seeds:
            run = out / "runs" / f"{name}_seed{seed}"
            ckpt, train_s = train(name, dataset, run, args.steps, seed)
            row = {"seed": seed, "train_s": train_s, "checkpoint": str(ckpt),
                   "held_out": score(ckpt, args.setting, args.skill, objects, args.episodes, args.eval_seed, args.workers,
                                     out / "eval" / f"{name}_seed{seed}")}
            if args.train_seed is not None:
                row["training_starts"] = score(ckpt, args.setting, args.skill, objects, args.train_episodes,
                                               args.train_seed, args.workers, out / "eval" / f"{name}_seed{seed}_train")
            rows.append(row)
            h = row["held_out"]
            print(f"{name:<18} seed {seed}: held-out {h['successes']}/{h['n']}"
                  + (f", training starts {row['training_starts']['successes']}/{row['training_starts']['n']}"
                     if "training_starts" in row else "") + f"  (train {train_s:.0f} s)", flush=True)
        summary["variants"][name] = {"config": VARIANTS[name], "runs": rows}
        out.mkdir(parents=True, exist_ok=True)
        (out / "bc_inputs.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"wrote {out / 'bc_inputs.json'}")
    return summary


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
