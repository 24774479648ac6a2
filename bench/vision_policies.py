"""Camera policies of the `vision` input tier on one skill, from a camera dataset to held-out success, their blind
controls, paired comparisons and learning curves, with the CLI's own commands (docs/experiments.md, "Policies that
see"):

    train    aerobench train bc --inputs vision --images RECIPE, one run per training seed (--seeds), and the blind
             control (--blind: the same network and training with the cameras blanked)
    eval     aerobench eval --inputs vision of each on the same held-out starts (--eval-seed, --per-object)
    compare  aerobench compare: each camera run against the blind control, and against --privileged (the results
             of a privileged row on the same starts: the vision gap)
    curves   the first seed's recipe on the leading fractions of the demonstrations (--fractions, train bc
             --max-transitions) and at fewer gradient steps (--curve-steps: the run resumed step by step, each
             checkpoint copied and evaluated on the same starts)

Every step leaves its folder under --out and a marker in --out/done/; rerunning the same command continues where it
stopped. Prints the table and writes `vision.json` (and a learning-curve PNG with --plot) under --out.

A curve of evaluations already run (runs trained by hand with one recipe and `train bc --max-transitions`, scored
on the same starts): `--curve-from FRACTION=RESULTS[,RESULTS]` once per point (several sets of starts pooled), with
the runs' --steps, --setting, --skill and --eval-seed; it writes `curve.json` under --out (and the PNG with --plot)
and trains nothing. With `--over steps` each point is `STEPS=RESULTS` instead: checkpoints of one run on all its
demonstrations, after that many gradient steps (--steps: the longest).

    python bench/vision_policies.py --dataset DATA --skill place --out outputs/vision/place [--seeds 0,1]
        [--steps 10000] [--per-object 20] [--eval-seed 4200] [--workers 2] [--fractions 0.25,0.5]
        [--curve-steps 2500,5000] [--privileged RESULTS] [--recipe "--batch-size 128"]
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import sys
import textwrap
from dataclasses import asdict, dataclass, field
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

from steps import Steps, aerobench  # noqa: E402


@dataclass(frozen=True)
class Budget:
    dataset: str
    skill: str = "place"
    setting: str = "PrepareGroceries"
    seeds: tuple[int, ...] = (0,)
    steps: int = 200
    recipe: str = "--batch-size 32"  # further `train bc` flags of every run (the recipe under test)
    blind: bool = True
    eval_seed: int = 4200
    per_object: int = 1
    objects: str | None = None  # comma-separated: evaluate these objects only (default: the setting's)
    workers: int = 1
    fractions: tuple[float, ...] = ()
    curve_steps: tuple[int, ...] = ()
    privileged: str | None = None  # results of a privileged row on the same starts

    def __post_init__(self):
        if any(not 0 < f < 1 for f in self.fractions) or any(not 0 < s < self.steps for s in self.curve_steps):
            raise ValueError("--fractions lie in (0, 1) and --curve-steps below --steps")
        if not self.seeds or self.per_object < 1 or self.workers < 1:
            raise ValueError("give at least one seed, --per-object and --workers of at least 1")


def train(steps: Steps, b: Budget, name: str, seed: int, *extra: object, until: int | None = None) -> Path:
    steps.run(f"{name}.{until or b.steps}", aerobench(
        "train", "bc", "--dataset", b.dataset, "--out", steps.out / name, "--inputs", "vision", "--images",
        "--steps", until or b.steps, "--seed", seed, "--no-progress", *shlex.split(b.recipe), *extra))
    return steps.out / name / "checkpoint"


def evaluate(steps: Steps, b: Budget, name: str, checkpoint: Path) -> dict:
    out = steps.out / name
    objects = ("--objects", b.objects) if b.objects else ()
    steps.run(name, aerobench("eval", "--policy", "bc", "--checkpoint", checkpoint, "--setting", b.setting,
                              "--skills", b.skill, *objects, "--episodes-per-object", b.per_object, "--seed",
                              b.eval_seed, "--workers", b.workers, "--inputs", "vision", "--out", out))
    return json.loads((out / "results.json").read_text())


def compare(steps: Steps, name: str, a: Path | str, b: Path | str) -> dict:
    out = steps.out / f"{name}.json"
    steps.run(name, aerobench("compare", a, b, "--json", out))
    return json.loads(out.read_text())


def row(name: str, results: dict, **facts) -> dict:
    from aerobench.eval.results import failure_modes, over_all_cells

    pooled = over_all_cells(results)
    seen = results["provenance"].get("seen_in_training") or {}
    return {"policy": name, **facts, "successes": pooled["successes"], "n": pooled["n"],
            "wilson95": pooled["wilson95"], "mean_sr": results["mean_sr"], "inputs": results["inputs"],
            "seen_in_training": seen.get("episodes"), "failure_modes": failure_modes(pooled["modes"])}


def total_frames(dataset: str) -> int:
    return int(json.loads((Path(dataset) / "meta" / "info.json").read_text())["total_frames"])


def run(b: Budget, out: Path) -> dict:
    steps = Steps(out, "vision")
    rows, comparisons, curve = [], {}, []
    for seed in b.seeds:
        name = f"camera_s{seed}"
        if seed == b.seeds[0]:  # the steps curve: the first run resumed step by step, each checkpoint kept
            for k in b.curve_steps:
                checkpoint = train(steps, b, name, seed, until=k)
                kept = out / f"{name}_at{k}"
                if not kept.exists():
                    shutil.copytree(checkpoint, kept / "checkpoint")
                curve.append(row(f"{name}_at{k}", evaluate(steps, b, f"eval_{name}_at{k}", kept / "checkpoint"),
                                 steps=k, fraction=1.0))
        results = evaluate(steps, b, f"eval_{name}", train(steps, b, name, seed))
        rows.append(row(name, results, steps=b.steps, fraction=1.0, seed=seed))
    first = steps.out / f"eval_camera_s{b.seeds[0]}"
    if b.blind:
        results = evaluate(steps, b, "eval_blind_s0", train(steps, b, "blind_s0", b.seeds[0], "--blind"))
        rows.append(row("blind_s0", results, steps=b.steps, fraction=1.0, seed=b.seeds[0]))
        for seed in b.seeds:
            comparisons[f"camera_s{seed} vs blind_s0"] = compare(
                steps, f"compare_camera_s{seed}_blind", steps.out / f"eval_camera_s{seed}", steps.out / "eval_blind_s0")
    if b.privileged:
        comparisons["camera_s0 vs privileged"] = compare(steps, "compare_camera_privileged", first, b.privileged)
    frames = total_frames(b.dataset)
    for fraction in b.fractions:
        name = f"camera_f{fraction:g}"
        checkpoint = train(steps, b, name, b.seeds[0], "--max-transitions", int(fraction * frames))
        curve.append(row(name, evaluate(steps, b, f"eval_{name}", checkpoint), steps=b.steps, fraction=fraction))
    curve.append({**rows[0], "policy": "camera_s0"})
    summary = {"budget": asdict(b), "rows": rows, "comparisons": {k: v["overall"] for k, v in comparisons.items()},
               "learning_curve": sorted(curve, key=lambda r: (r["fraction"], r["steps"]))}
    (out / "vision.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def table(summary: dict) -> str:
    lines = ["| policy | steps | data | held out | Wilson 95% | seen in training | failure modes |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in summary["rows"] + [c for c in summary["learning_curve"] if c["policy"] != "camera_s0"]:
        modes = ", ".join(f"{m} {c}" for m, c in r["failure_modes"].items()) or "-"
        lo, hi = r["wilson95"]
        lines.append(f"| {r['policy']} | {r['steps']} | {r['fraction']:.0%} | {r['successes']}/{r['n']} | "
                     f"{100 * lo:.1f}-{100 * hi:.1f} | {r['seen_in_training']} | {modes} |")
    for name, c in summary["comparisons"].items():
        lo, hi = c["diff95"]
        lines.append(f"\n{name}: {c['only_a']} won by A only, {c['only_b']} by B only of {c['n']}; difference "
                     f"{100 * lo:.1f} to {100 * hi:.1f} points, McNemar p = {c['p_value']:.3g}: {c['verdict']}")
    return "\n".join(lines)


def curve_from(points: list[str], steps: int, setting: str, skill: str, eval_seed: str, out: Path,
               over: str = "fraction") -> dict:
    """The learning curve of evaluations already run: `FRACTION=RESULTS[,RESULTS...]` per point (results.json files or
    their folders; several, e.g. two sets of held-out starts, are pooled episode by episode); with `over="steps"`,
    `STEPS=RESULTS...`: one run's checkpoints on all its data."""
    from aerobench.eval.results import over_all_cells

    curve = []
    for point in points:
        x, _, paths = point.partition("=")
        runs = []
        for path in paths.split(","):
            path = Path(path) / "results.json" if Path(path).is_dir() else Path(path)
            if not path.is_file():
                raise SystemExit(f"--curve-from {point}: no results at {path} (FRACTION=RESULTS[,RESULTS])")
            runs.append((str(path), json.loads(path.read_text())))
        cells = [c for _, r in runs for c in r["cells"]]
        pooled = {**runs[0][1], "cells": cells, "mean_sr": over_all_cells({"cells": cells})["success_rate"]}
        at = dict(steps=int(x), fraction=1.0) if over == "steps" else dict(steps=steps, fraction=float(x))
        curve.append(row(runs[0][1]["label"], pooled, **at, sources=[p for p, _ in runs]))
    summary = {"budget": {"steps": steps, "setting": setting, "skill": skill, "eval_seed": eval_seed},
               "rows": [], "comparisons": {}, "learning_curve": sorted(curve, key=lambda r: r[over])}
    out.mkdir(parents=True, exist_ok=True)
    (out / "curve.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def plot(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curve = summary["learning_curve"]
    panels = (("fraction", [r for r in curve if r["steps"] == summary["budget"]["steps"]]),
              ("steps", [r for r in curve if r["fraction"] == 1.0]))
    panels = [(key, xs) for key, xs in panels if len({r[key] for r in xs}) > 1]  # a panel with one x says nothing
    fig, axes = plt.subplots(1, len(panels), figsize=(4.5 * len(panels), 3.4), squeeze=False)
    for ax, (key, xs) in zip(axes[0], panels):
        xs = sorted(xs, key=lambda r: r[key])
        rate = [r["successes"] / r["n"] for r in xs]
        lo = [r["wilson95"][0] for r in xs]
        hi = [r["wilson95"][1] for r in xs]
        ax.plot([r[key] for r in xs], rate, "o-")
        ax.fill_between([r[key] for r in xs], lo, hi, alpha=0.2)
        ax.set_xlabel("fraction of the demonstrations" if key == "fraction" else "gradient steps")
        ax.set_ylabel("held-out success")
        ax.set_ylim(0, 1)
    title = (f"vision-tier BC, {summary['budget']['setting']} {summary['budget']['skill']} "
             f"(seed {summary['budget']['eval_seed']}, Wilson 95%)")
    fig.suptitle("\n".join(textwrap.wrap(title, 45 * len(panels))), fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def parse(argv: list[str] | None = None) -> tuple[Budget, Path, Path | None]:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--dataset", required=True, help="a camera dataset of the skill (aerobench generate, merged)")
    for name, f in Budget.__dataclass_fields__.items():
        if name == "dataset":
            continue
        default = f.default if f.default is not field().default else None
        kind = {tuple: str, bool: None}.get(type(default), str if default is None else type(default))
        if kind is None:
            p.add_argument(f"--{name.replace('_', '-')}", action=argparse.BooleanOptionalAction, default=None)
        else:
            p.add_argument(f"--{name.replace('_', '-')}", type=kind, default=None, help=f"default {default}")
    p.add_argument("--out", default="outputs/bench/vision")
    p.add_argument("--plot", type=Path, help="write the learning curves here (PNG)")
    args = p.parse_args(argv)
    chosen = {k: v for k, v in vars(args).items() if k in Budget.__dataclass_fields__ and v is not None}
    for key, kind in (("seeds", int), ("fractions", float), ("curve_steps", int)):
        if isinstance(chosen.get(key), str):
            chosen[key] = tuple(kind(x) for x in chosen[key].split(",") if x)
    try:
        return Budget(**chosen), Path(args.out), args.plot
    except ValueError as e:
        p.error(str(e))


def main(argv: list[str] | None = None) -> dict:
    argv = sys.argv[1:] if argv is None else argv
    if "--curve-from" in argv:
        p = argparse.ArgumentParser(description="a learning curve from evaluations already run")
        p.add_argument("--curve-from", action="append", required=True, metavar="FRACTION=RESULTS")
        p.add_argument("--over", choices=("fraction", "steps"), default="fraction",
                       help="what each point's number is: the fraction of the demonstrations or the gradient steps")
        p.add_argument("--steps", type=int, required=True)
        p.add_argument("--setting", default="PrepareGroceries")
        p.add_argument("--skill", default="place")
        p.add_argument("--eval-seed", required=True, help="the held-out starts' --seed (several: comma-separated)")
        p.add_argument("--out", type=Path, default=Path("outputs/bench/vision"))
        p.add_argument("--plot", type=Path)
        a = p.parse_args(argv)
        summary = curve_from(a.curve_from, a.steps, a.setting, a.skill, a.eval_seed, a.out, a.over)
        print(table(summary))
        if a.plot:
            plot(summary, a.plot)
        print(f"wrote {a.out / 'curve.json'}")
        return summary
    budget, out, png = parse(argv)
    summary = run(budget, out)
    print(table(summary))
    if png:
        plot(summary, png)
    print(f"wrote {out / 'vision.json'}")
    return summary


if __name__ == "__main__":
    main()
