"""The leaderboard's robustness view: each run under an evaluation condition or in real time, beside the nominal run
of the same policy on the same starts, with the paired difference (`compare`: exact McNemar, Newcombe's interval).

A conditioned run pairs with a nominal one when both evaluated the same policy and checkpoint on the same episode
plan (setting, skills, objects, episodes per object, `--seed`) with the same flight controller; the view says nothing about a run without its nominal
twin (it is listed as unpaired), so "drops 30 points in a 3 m/s gust" is only ever a paired statement.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from .compare import Run, compare, run_from_results
from .results import median
from .row_facts import perturbation


def _plan(result: dict) -> tuple:
    provenance = result["provenance"]
    return (result["setting"], result["policy"], str(provenance.get("checkpoint")), provenance.get("seed"),
            tuple(provenance.get("chain") or ()), tuple(provenance.get("skills") or ()),
            tuple(provenance.get("objects") or ()), provenance.get("episodes_per_object"), provenance.get("max_steps"),
            provenance.get("controller", "payload-aware"))


def _run(result: dict) -> Run:
    return run_from_results(Path(result.get("_path") or "results.json"), result)


def _tilt(result: dict) -> str:
    """The median over a run's episodes of their largest tilt, in degrees ("-" where the results do not say)."""
    tilts = [t for c in result["cells"] for t in (c.get("flight") or {}).get("max_tilt_deg_per_episode", ())]
    return f"{median(tilts):.1f}" if tilts else "-"


def _saturation(result: dict | None) -> str:
    """The median over a run's episodes of the share of control steps with a clipped rotor, in percent ("-" where
    the results do not record it: runs before `rotor_statistics`)."""
    shares = [s for c in (result or {}).get("cells", ()) for s in (c.get("flight") or {}).get("saturated_share_per_episode", ())]
    return f"{100 * median(shares):.1f}" if shares else "-"


def robustness_rows(results: Sequence[dict]) -> list[dict]:
    """One row per perturbed run: `{"result", "nominal", "perturbation", "comparison"}`, the comparison None when the
    nominal twin is missing or its episodes cannot be paired."""
    nominal = {}
    for result in results:
        if not perturbation(result) and not result.get("training_runs"):
            nominal.setdefault(_plan(result), result)
    rows = []
    for result in results:
        change = perturbation(result)
        if not change:
            continue
        twin = nominal.get(_plan(result))
        comparison = None
        if twin is not None:
            try:
                comparison = compare(_run(twin), _run(result))
            except ValueError:  # an older results file without per-episode outcomes: unpaired
                comparison = None
        rows.append({"result": result, "nominal": twin, "perturbation": change, "comparison": comparison})
    return rows


def robustness_markdown(results: Sequence[dict], name) -> list[str]:
    """The view as Markdown lines (none without a perturbed run); `name(result)` is the row's short name."""
    rows = robustness_rows(results)
    if not rows:
        return []
    lines = ["", "### Robustness: conditions and real-time evaluation", "",
             "Each perturbed run beside the nominal run of the same policy and checkpoint on the same starts. Change: "
             "perturbed minus nominal success, in points, with its paired 95% interval (Newcombe) and the exact "
             "McNemar p-value over the episodes both runs scored (docs/robustness.md). Tilt: the median over "
             "episodes of each episode's largest tilt, nominal -> perturbed (records that carry it). Saturated: the "
             "median over episodes of the share of control steps at which a rotor's commanded thrust was clipped (at "
             "zero or at its maximum), nominal -> perturbed.", "",
             "| Row | Inputs | Perturbation | Paired episodes | Nominal % | Perturbed % | Change (pts) [95%] | p | "
             "Tilt, median max (deg) | Saturated, median (% of steps) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        result, cmp = row["result"], row["comparison"]
        inputs = result.get("inputs", "-")
        if cmp is None:
            lines.append(f"| {name(result)} | {inputs} | {row['perturbation']} | unpaired: no nominal run of this "
                         f"checkpoint on these starts | - | {100 * result['mean_sr']:.1f} (mean S.R.) | - | - | "
                         f"{_tilt(result)} | {_saturation(result)} |")
            continue
        overall = cmp["overall"]
        lo, hi = overall["diff95"]  # nominal minus perturbed
        lines.append(f"| {name(result)} | {inputs} | {row['perturbation']} | {overall['n']} | "
                     f"{100 * overall['rate_a']:.1f} | {100 * overall['rate_b']:.1f} | "
                     f"{100 * (overall['rate_b'] - overall['rate_a']):+.1f} [{-100 * hi:+.1f}, {-100 * lo:+.1f}] | "
                     f"{overall['p_value']:.3g} | {_tilt(row['nominal'])} -> {_tilt(result)} | "
                     f"{_saturation(row['nominal'])} -> {_saturation(result)} |")
    return lines
