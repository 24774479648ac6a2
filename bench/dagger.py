"""DAgger (Ross et al., 2011) on one skill of one setting, from an empty folder to a held-out success table, with the
CLI's own commands (the ones docs/experiments.md, "PrepareGroceries Open: DAgger", lists):

    round 0   aerobench generate --policy expert --action-noise SIGMA (DART demonstrations, successes kept)
              aerobench train bc on them -> bc0
    round k   aerobench generate --policy bc --checkpoint bc(k-1) --label-with expert --keep all (bc(k-1) flies,
              the expert labels every state it reaches; every outcome kept)
              aerobench dataset join demos r1 .. rk -> jk;  aerobench train bc --outcomes S,F,T on jk -> bck
    each k    aerobench eval of bck on the same held-out starts (`--eval-seed`)
    at last   with `--final-per-object N`: the last round's policy on N other starts (`--final-seed`), decided before
              any evaluation was seen

Generation runs in `--workers` shard processes (physx_cpu: one env per process), evaluation with `--workers`. Every
step leaves its folder under `--out` and a marker in `--out/done/`; rerunning the same command continues where it
stopped (an interrupted generation resumes its shards without repeating an episode). Prints the table and writes
`dagger.json` under `--out`.

The defaults are a smoke-sized budget (minutes on a CPU); `--full` sets the documented Open run (240 DART
demonstrations, 4 rounds of 200, 20k BC steps, 20 held-out starts, 60 final ones; about an hour on two cores).

    python bench/dagger.py [--setting PrepareGroceries] [--skill open] [--rounds 1] [--workers 1] [--out DIR]
    python bench/dagger.py --full --skill close --workers 2 --out outputs/dagger/PrepareGroceries_close
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import asdict, dataclass, replace
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

from steps import Steps, aerobench  # noqa: E402

# The Open BC's inputs (docs/experiments.md: one frame, no velocity readings, the doorway and the arm).
ARTICULATION_FIELDS = ("skill,goal_pos,goal_pos_body,tcp_to_obj_pos,heading_error,progress,is_grasp_confirmed,"
                       "gravity_body_xy,altitude,grasp_side_room,doorway_ahead,doorway_pos,arm_position")


@dataclass(frozen=True)
class Budget:
    setting: str = "PrepareGroceries"
    skill: str = "open"
    demos: int = 4
    demo_seed: int = 500
    action_noise: float = 0.05  # DART on the demonstrations (aerobench.rollout.noise)
    rounds: int = 1
    episodes_per_round: int = 2
    round_seed: int = 700  # round k flies seed round_seed + k - 1
    bc_steps: int = 200
    bc_seed: int = 0
    history: int = 1
    task_fields: str | None = ARTICULATION_FIELDS  # None: every task-state field
    phase_onset_weight: float = 20.0
    eval_per_object: int = 1
    eval_seed: int = 4200
    final_per_object: int = 0
    final_seed: int = 4250
    workers: int = 1

    def __post_init__(self):
        if self.demos < 1 or self.rounds < 0 or self.episodes_per_round < 1 or self.workers < 1:
            raise ValueError("--demos, --episodes-per-round and --workers must be at least 1, --rounds at least 0")
        seeds = {self.demo_seed, *range(self.round_seed, self.round_seed + self.rounds)}
        if {self.eval_seed, self.final_seed} & seeds:
            raise ValueError("the evaluation seeds must differ from the demonstration and round seeds (held out)")


FULL = dict(demos=240, rounds=4, episodes_per_round=200, bc_steps=20_000, eval_per_object=20, final_per_object=60)


def generate(steps: Steps, b: Budget, name: str, episodes: int, seed: int, *policy_args: object) -> Path:
    """`episodes` state-only episodes into out/<name>, in `workers` shards, then merged."""
    folder = steps.out / name
    base = ("generate", "--setting", b.setting, "--skills", b.skill, "--episodes", episodes, "--no-cameras",
            "--seed", seed, *policy_args, "--out", folder)
    shards = min(b.workers, episodes)
    steps.run(name, *[aerobench(*base, "--shard", f"{i}/{shards}") for i in range(shards)])
    steps.run(f"{name}.merge", aerobench("dataset", "merge", folder))
    return folder


def train(steps: Steps, b: Budget, name: str, dataset: Path, *extra: object) -> Path:
    fields = ("--task-fields", b.task_fields) if b.task_fields else ()
    steps.run(name, aerobench("train", "bc", "--dataset", dataset, "--out", steps.out / name, "--steps", b.bc_steps,
                              "--seed", b.bc_seed, "--history", b.history, *fields,
                              "--phase-onset-weight", b.phase_onset_weight, *extra))
    return steps.out / name / "checkpoint"


def evaluate(steps: Steps, b: Budget, name: str, checkpoint: Path, per_object: int, seed: int) -> dict:
    out = steps.out / name
    steps.run(name, aerobench("eval", "--policy", "bc", "--checkpoint", checkpoint, "--setting", b.setting,
                              "--skills", b.skill, "--episodes-per-object", per_object, "--seed", seed,
                              "--workers", b.workers, "--out", out))
    return json.loads((out / "results.json").read_text())


def dataset_size(folder: Path) -> tuple[int, int]:
    """(episodes, frames) of a merged dataset; (0, 0) when no episode was kept."""
    info = folder / "meta" / "info.json"
    if not info.is_file():
        return 0, 0
    meta = json.loads(info.read_text())
    return int(meta["total_episodes"]), int(meta["total_frames"])


def summary_row(name: str, data: Path, results: dict, seed: int) -> dict:
    """One table row: the data a policy trained on and its held-out success, failure modes and training overlap."""
    from aerobench.eval.results import failure_modes, over_all_cells

    pooled = over_all_cells(results)
    episodes, frames = dataset_size(data)
    seen = results["provenance"].get("seen_in_training") or {}
    return {"policy": name, "data": str(data), "episodes": episodes, "frames": frames, "eval_seed": seed,
            "successes": pooled["successes"], "n": pooled["n"], "wilson95": pooled["wilson95"],
            "seen_in_training": seen.get("episodes"), "failure_modes": failure_modes(pooled["modes"])}


def run(b: Budget, out: Path) -> dict:
    steps = Steps(out, "dagger")
    demos = generate(steps, b, "demos", b.demos, b.demo_seed, "--policy", "expert", "--action-noise", b.action_noise)
    if dataset_size(demos)[0] == 0:
        raise SystemExit(f"[dagger] the expert kept no demonstration in {demos}; nothing to train on")
    checkpoint = train(steps, b, "bc0", demos)
    rows = [summary_row("bc0", demos, evaluate(steps, b, "eval0", checkpoint, b.eval_per_object, b.eval_seed),
                        b.eval_seed)]
    sources = [demos]
    for k in range(1, b.rounds + 1):
        sources.append(generate(steps, b, f"r{k}", b.episodes_per_round, b.round_seed + k - 1, "--policy", "bc",
                                "--checkpoint", checkpoint, "--label-with", "expert", "--keep", "all"))
        joined = out / f"j{k}"
        steps.run(f"j{k}", aerobench("dataset", "join", *[s for s in sources if dataset_size(s)[0]], "--out", joined))
        checkpoint = train(steps, b, f"bc{k}", joined, "--outcomes", "S,F,T")
        rows.append(summary_row(f"bc{k}", joined, evaluate(steps, b, f"eval{k}", checkpoint, b.eval_per_object,
                                                           b.eval_seed), b.eval_seed))
    final = None
    if b.final_per_object:
        last = rows[-1]
        # named after its policy: a run continued with more rounds evaluates its new last policy, not the old one's
        final = summary_row(last["policy"], Path(last["data"]), evaluate(
            steps, b, f"final_{last['policy']}", checkpoint, b.final_per_object, b.final_seed), b.final_seed)
    summary = {"budget": asdict(b), "rounds": rows, "final": final, "checkpoint": str(checkpoint)}
    (out / "dagger.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def table(summary: dict) -> str:
    lines = ["| policy | episodes | frames | held out (seed) | seen in training | failure modes |",
             "| --- | --- | --- | --- | --- | --- |"]
    for row in summary["rounds"] + ([summary["final"]] if summary["final"] else []):
        modes = ", ".join(f"{m} {c}" for m, c in row["failure_modes"].items()) or "-"
        lines.append(f"| {row['policy']} | {row['episodes']} | {row['frames']:,} | {row['successes']}/{row['n']} "
                     f"({row['eval_seed']}) | {row['seen_in_training']} | {modes} |")
    return "\n".join(lines)


def parse(argv: list[str] | None = None) -> tuple[Budget, Path]:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--full", action="store_true", help="the documented run's sizes: " + json.dumps(FULL))
    for field, default in asdict(Budget()).items():
        p.add_argument("--" + field.replace("_", "-"), type=type(default) if default is not None else str,
                       default=None, help=f"default {default}")
    p.add_argument("--out", default="outputs/bench/dagger")
    args = p.parse_args(argv)
    budget = Budget(**FULL) if args.full else Budget()
    chosen = {f: v for f, v in vars(args).items() if f in asdict(budget) and v is not None}
    try:
        return replace(budget, **chosen), Path(args.out)
    except ValueError as e:
        p.error(str(e))


def main(argv: list[str] | None = None) -> dict:
    budget, out = parse(argv)
    summary = run(budget, out)
    print(table(summary))
    print(f"wrote {out / 'dagger.json'}")
    return summary


if __name__ == "__main__":
    main()
