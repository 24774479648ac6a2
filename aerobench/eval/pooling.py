"""One leaderboard row from several training runs of one recipe (results files sharing a `--label`).

A policy's success depends on its training seed as well as on the evaluation episodes, and one lucky seed looks like
a good recipe. Results files with the same label but different checkpoints are pooled into one row: each cell's
counts are summed (its success ± binomial SE is then over all runs' episodes), and the row also reports every
run's Mean S.R., their mean and a bootstrap 95% interval over the runs (resampling runs, not episodes), so the
spread between seeds is visible beside the per-episode SE.
"""

from __future__ import annotations

import random
from collections import Counter
from collections.abc import Sequence

from .results import rate_fields
from .stats import standard_error

BOOTSTRAP_SAMPLES = 10_000
BOOTSTRAP_SEED = 0  # the interval is part of a committed table: the same runs give the same interval


def bootstrap_mean_interval(values: Sequence[float], samples: int = BOOTSTRAP_SAMPLES) -> tuple[float, float]:
    """Percentile bootstrap 95% interval of the mean of `values` (resampled with replacement)."""
    if not values:
        raise ValueError("no values to bootstrap")
    rng = random.Random(BOOTSTRAP_SEED)
    means = sorted(sum(rng.choices(values, k=len(values))) / len(values) for _ in range(samples))
    return means[int(0.025 * (samples - 1))], means[int(0.975 * (samples - 1))]


def _pooled_cell(cells: list[dict]) -> dict:
    cell = {key: cells[0][key] for key in ("skill", "object")}
    cell.update(rate_fields(sum(c["successes"] for c in cells), sum(c["n"] for c in cells)),
                init_failures=sum(c["init_failures"] for c in cells))
    for key in ("outcomes", "modes", "causes"):
        cell[key] = dict(sum((Counter(c[key]) for c in cells), Counter()))
    return cell


def _pooled_chains(results: list[dict]) -> dict:
    chains: dict[str, dict[int, dict]] = {}
    for result in results:
        for name, stages in result.get("chains", {}).items():
            for s in stages:
                pooled = chains.setdefault(name, {}).setdefault(s["stage"], {**s, "reached": 0, "successes": 0, "modes": {}})
                pooled["reached"] += s["reached"]
                pooled["successes"] += s["successes"]
                pooled["modes"] = dict(Counter(pooled["modes"]) + Counter(s["modes"]))
    out = {}
    for name, stages in chains.items():
        out[name] = []
        for stage in sorted(stages):
            s = stages[stage]
            n, k = s["reached"], s["successes"]
            out[name].append({**s, "conditional_success": k / n if n else 0.0, "se": standard_error(k, n)})
    return out


def pool_training_runs(results: list[dict]) -> dict:
    """One results document from several runs of one recipe on one setting (each its own checkpoint)."""
    checkpoints = [r["provenance"].get("checkpoint") for r in results]
    if len(set(checkpoints)) != len(checkpoints):
        raise ValueError(f"two results for {results[0]['label']!r} on {results[0]['setting']} with the same checkpoint "
                         f"({', '.join(r.get('_source', '?') for r in results)}); pass one, or give one a different "
                         f"--label when evaluating")
    groups: dict[tuple[str, str], list[dict]] = {}
    for result in results:
        for cell in result["cells"]:
            groups.setdefault((cell["skill"], cell["object"]), []).append(cell)
    cells = [_pooled_cell(group) for group in groups.values()]
    scored = [c for c in cells if c["n"]]
    per_skill: dict[str, list[float]] = {}
    for cell in scored:
        per_skill.setdefault(cell["skill"], []).append(cell["success_rate"])
    run_means = [r["mean_sr"] for r in results]
    pooled = {key: value for key, value in results[0].items() if key not in ("cells", "chains", "episodes")}
    pooled.update(
        cells=cells, episodes=sum(r["episodes"] for r in results),
        mean_sr=sum(c["success_rate"] for c in scored) / len(scored) if scored else 0.0,
        skill_mean_sr={s: sum(v) / len(v) for s, v in per_skill.items()}, chains=_pooled_chains(results),
        training_runs={"sources": [r.get("_source", "?") for r in results], "checkpoints": checkpoints,
                       "mean_sr": run_means, "mean": sum(run_means) / len(run_means),
                       "bootstrap95": list(bootstrap_mean_interval(run_means))},
    )
    commands = list(dict.fromkeys(r["provenance"].get("command") or "-" for r in results))
    # no records: a pooled row is not paired episode by episode with another row (`compare` skips it)
    pooled["provenance"] = {**results[0]["provenance"], "records": None, "command": " ; ".join(commands)}
    pooled["_source"] = " + ".join(r.get("_source", "?") for r in results)
    return pooled


def training_runs_text(result: dict) -> str:
    """"-" for one run; else every run's Mean S.R., their mean and the bootstrap interval over runs."""
    runs = result.get("training_runs")
    if not runs:
        return "-"
    lo, hi = runs["bootstrap95"]
    rates = ", ".join(f"{100 * v:.1f}" for v in runs["mean_sr"])
    return (f"{len(runs['mean_sr'])} runs: {rates} (mean {100 * runs['mean']:.1f}, bootstrap 95% over runs "
            f"{100 * lo:.1f}-{100 * hi:.1f})")
