"""`aerobench compare A B`: two policies on the same evaluation starts, compared episode by episode.

Two evals made with the same setting, skills, objects and `--seed` run the same planned episodes (index, seed, skill,
object), so their outcomes pair up. Per skill-object cell and overall: the paired table (both succeed / only A /
only B / neither), the exact McNemar p-value, a 95% interval for rate(A) - rate(B) (Newcombe's method 10 for paired
data) and a verdict in words; across the cells, Holm's correction of their p-values says which cells differ. Starts
that either run rejected at initialization (outcome I) are left out of the pairs. Results whose starts differ are
refused with one line.

`--diagnostic NAME` pairs a per-episode record diagnostic instead (e.g. `min_tcp_to_grasp_point_m`: how near the jaws
came to the grasp point when no episode succeeded): medians, on how many starts A's value is lower, and the
two-sided Wilcoxon signed-rank test of the paired differences (scipy's: exact for small n without ties).
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..rollout.records import read_records
from .results import load_results
from .stats import holm_adjusted, mcnemar_sample_size, paired_comparison, paired_difference_interval

ALPHA = 0.05
POWER = 0.8
OVERALL = ("all", "")


@dataclass(frozen=True)
class Run:
    """One eval: its results and its episodes `{index: (seed, skill, object, outcome)}`."""

    path: Path
    results: dict
    episodes: dict[int, tuple]

    @property
    def label(self) -> str:
        return self.results.get("label") or self.results["policy"]


def load_run(path: str | Path) -> Run:
    """An eval folder (`DIR/results.json` and its records) or a results file with per-episode outcomes."""
    path = Path(path)
    file = path / "results.json" if path.is_dir() else path
    return run_from_results(file, load_results(file))


def _records_beside(file: Path, results: dict) -> list[Path]:
    """The episode records a results file names (`provenance.records`, beside it); empty if any is missing."""
    records = [file.parent / r for r in str(results["provenance"].get("records") or "").split(",") if r]
    return records if records and all(r.is_file() for r in records) else []


def run_from_results(file: Path, results: dict) -> Run:
    """The run of a loaded results document (`file` locates the records of an older results file)."""
    episodes = {}
    for cell in results["cells"]:
        for index, seed, outcome in cell.get("episodes", ()):
            episodes[int(index)] = (seed, cell["skill"], cell["object"], outcome)
    if not episodes:  # results written before cells listed their episodes: read the records beside them
        records = _records_beside(file, results)
        if not records:
            raise ValueError(f"{file} lists no per-episode outcomes and its records are not beside it: re-run "
                             f"`aerobench summarize` on its eval folder, or pass the eval folder")
        for r in (row for f in records for row in read_records(f)):
            episodes[int(r["episode_index"])] = (r["seed"], r["skill"], r["object"], r["outcome"])
    return Run(file, results, episodes)


def _diagnostics(run: Run, name: str) -> dict[int, float]:
    """`{episode index: value}` of record diagnostic `name` in the records beside `run`'s results (None left out)."""
    records = _records_beside(run.path, run.results)
    if not records:
        raise ValueError(f"--diagnostic reads the episode records beside {run.path}: pass its eval folder")
    rows = [row for f in records for row in read_records(f)]
    known = {k for row in rows for k in (row.get("diagnostics") or {})}
    if name not in known:
        raise ValueError(f"no record diagnostic {name!r} in {run.path.parent}; known: {', '.join(sorted(known))}")
    return {int(r["episode_index"]): float(r["diagnostics"][name]) for r in rows
            if r["outcome"] != "I" and (r.get("diagnostics") or {}).get(name) is not None}


def compare_diagnostic(a: str | Path | Run, b: str | Path | Run, name: str) -> dict:
    """A record diagnostic of two evals on the same starts, start by start: medians and ranges, on how many starts
    A is lower / higher, and the two-sided Wilcoxon signed-rank p-value of the differences."""
    from scipy.stats import wilcoxon  # scipy on first use: `compare` alone does not need it

    a = a if isinstance(a, Run) else load_run(a)
    b = b if isinstance(b, Run) else load_run(b)
    _check_same_starts(a, b)
    va, vb = _diagnostics(a, name), _diagnostics(b, name)
    keys = sorted(set(va) & set(vb))
    if not keys:
        raise ValueError(f"no start has {name!r} in both evals")
    xa, xb = [va[k] for k in keys], [vb[k] for k in keys]
    differ = any(x != y for x, y in zip(xa, xb))
    p = float(wilcoxon(xa, xb).pvalue) if differ else 1.0

    def spread(values: list[float]) -> dict:
        return {"median": statistics.median(values), "min": min(values), "max": max(values)}

    return {"diagnostic": name, "n": len(keys), "a": {"label": a.label, "path": str(a.path), **spread(xa)},
            "b": {"label": b.label, "path": str(b.path), **spread(xb)},
            "a_lower": sum(x < y for x, y in zip(xa, xb)), "a_higher": sum(x > y for x, y in zip(xa, xb)),
            "p_value": p, "test": "Wilcoxon signed-rank, two-sided (scipy.stats.wilcoxon)"}


def format_diagnostic(cmp: Mapping) -> str:
    a, b = cmp["a"], cmp["b"]
    return "\n".join([
        f"{cmp['diagnostic']}, {cmp['n']} paired starts",
        f"A: {a['label']}  median {a['median']:.3g} ({a['min']:.3g} to {a['max']:.3g})  ({a['path']})",
        f"B: {b['label']}  median {b['median']:.3g} ({b['min']:.3g} to {b['max']:.3g})  ({b['path']})",
        f"A lower on {cmp['a_lower']} of {cmp['n']}, higher on {cmp['a_higher']}; p = {cmp['p_value']:.2g} "
        f"({cmp['test']})"])


def _check_same_starts(a: Run, b: Run) -> None:
    why = None
    if a.results["setting"] != b.results["setting"]:
        why = f"settings {a.results['setting']} and {b.results['setting']}"
    elif a.results["provenance"].get("seed") != b.results["provenance"].get("seed"):
        why = f"--seed {a.results['provenance'].get('seed')} and {b.results['provenance'].get('seed')}"
    elif {i: e[:3] for i, e in a.episodes.items()} != {i: e[:3] for i, e in b.episodes.items()}:
        why = f"different episode plans ({len(a.episodes)} and {len(b.episodes)} episodes; skills, objects or counts differ)"
    if why:
        raise ValueError(f"{a.path} and {b.path} do not share their starts ({why}): compare two evals of the same "
                         f"setting, skills, objects, --episodes-per-object and --seed")


def _decision(row: dict, difference: float) -> str:
    """The verdict in two words: A better, B better, no detectable difference, underpowered, no paired episodes."""
    if row["n"] == 0:
        return "no paired episodes"
    if row["p_value"] < ALPHA:
        return "A better" if row["only_a"] > row["only_b"] else "B better"
    lo, hi = row["diff95"]
    return "no detectable difference" if -difference < lo and hi < difference else "underpowered"


def _verdict(row: dict, difference: float) -> str:
    decision = _decision(row, difference)
    if decision == "no detectable difference":
        return f"no detectable difference at this n (95% interval within +-{100 * difference:.0f} points)"
    if decision == "underpowered":
        return (f"underpowered: about {row['n_needed']} paired episodes would detect a {100 * difference:.0f}-point "
                f"difference ({100 * POWER:.0f}% power)")
    return decision


def _paired_row(a: dict[int, bool], b: dict[int, bool], difference: float) -> dict:
    """Counts, p-value, interval and verdict of the paired successes `{episode index: success}` of A and B."""
    if not a:
        row = {"n": 0, "both": 0, "only_a": 0, "only_b": 0, "neither": 0, "rate_a": 0.0, "rate_b": 0.0, "p_value": 1.0,
               "diff95": [-1.0, 1.0], "n_needed": mcnemar_sample_size(0.0, difference, POWER, ALPHA)}
        return {**row, "decision": _decision(row, difference), "verdict": _verdict(row, difference)}
    pc = paired_comparison(a, b)
    row = {"n": pc.n, "both": pc.both, "only_a": pc.only_a, "only_b": pc.only_b, "neither": pc.neither,
           "rate_a": (pc.both + pc.only_a) / pc.n, "rate_b": (pc.both + pc.only_b) / pc.n, "p_value": pc.p_value,
           "diff95": list(paired_difference_interval(pc.both, pc.only_a, pc.only_b, pc.neither)),
           "n_needed": mcnemar_sample_size((pc.only_a + pc.only_b) / pc.n, difference, POWER, ALPHA)}
    return {**row, "decision": _decision(row, difference), "verdict": _verdict(row, difference)}


def _holm(rows: list[dict]) -> dict:
    """Holm-adjusted p-values of the cells with paired episodes (written into the rows as `p_holm`) and the cells that
    differ at family-wise alpha."""
    tested = [row for row in rows if row["n"]]
    for row, p in zip(tested, holm_adjusted([row["p_value"] for row in tested])):
        row["p_holm"] = p
    differ = [row for row in tested if row["p_holm"] < ALPHA]
    return {"cells": len(tested),
            "a_better": [[r["skill"], r["object"]] for r in differ if r["only_a"] > r["only_b"]],
            "b_better": [[r["skill"], r["object"]] for r in differ if r["only_b"] > r["only_a"]]}


def holm_text(cmp: Mapping) -> str:
    """One sentence: which cells differ after Holm's correction over the comparison's cells."""
    holm = cmp["holm"]

    def cells(found: list) -> str:
        return "none" if not found else f"{len(found)} ({', '.join(f'{s} {o}'.strip() for s, o in found)})"

    return (f"Holm over the {holm['cells']} cells (family-wise alpha {ALPHA}): A better in {cells(holm['a_better'])}, "
            f"B better in {cells(holm['b_better'])}")


def compare(a: str | Path | Run, b: str | Path | Run, difference: float = 0.10) -> dict:
    """The paired comparison of two evals, per cell and overall; `difference` is the effect size (in rate) the
    verdict's power statement is about."""
    if not 0 < difference < 1:
        raise ValueError(f"--difference must be between 0 and 1 (a success-rate difference), got {difference}")
    a = a if isinstance(a, Run) else load_run(a)
    b = b if isinstance(b, Run) else load_run(b)
    _check_same_starts(a, b)
    cells: dict[tuple[str, str], tuple[dict[int, bool], dict[int, bool]]] = {}
    excluded = 0
    for index in sorted(a.episodes):
        _, skill, obj, out_a = a.episodes[index]
        out_b = b.episodes[index][3]
        if "I" in (out_a, out_b):
            excluded += 1
            continue
        success_a, success_b = cells.setdefault((skill, obj or ""), ({}, {}))
        success_a[index], success_b[index] = out_a == "S", out_b == "S"
    rows = [{"skill": s, "object": o, **_paired_row(*pair, difference)} for (s, o), pair in cells.items()]
    holm = _holm(rows)
    every_a = {i: v for pair in cells.values() for i, v in pair[0].items()}
    every_b = {i: v for pair in cells.values() for i, v in pair[1].items()}
    overall = {"skill": OVERALL[0], "object": OVERALL[1], **_paired_row(every_a, every_b, difference)}
    return {"a": {"label": a.label, "path": str(a.path)}, "b": {"label": b.label, "path": str(b.path)},
            "setting": a.results["setting"], "seed": a.results["provenance"].get("seed"),
            "excluded_init_failures": excluded, "difference": difference, "cells": rows, "overall": overall, "holm": holm,
            "interval": "Newcombe (1998) method 10, paired", "test": "exact McNemar, two-sided"}


def format_comparison(cmp: Mapping) -> str:
    lines = [f"A: {cmp['a']['label']}  ({cmp['a']['path']})", f"B: {cmp['b']['label']}  ({cmp['b']['path']})",
             f"{cmp['setting']}, --seed {cmp['seed']}; paired episodes (starts rejected by either run left out: "
             f"{cmp['excluded_init_failures']})",
             f"{'skill':<8} {'object':<17} {'n':>4} {'both':>5} {'A only':>6} {'B only':>6} {'neither':>7} "
             f"{'A %':>6} {'B %':>6} {'A-B 95% (pts)':>15} {'p':>7}  verdict"]
    for row in [*cmp["cells"], cmp["overall"]]:
        lo, hi = row["diff95"]
        lines.append(f"{row['skill']:<8} {row['object'] or '-':<17} {row['n']:>4} {row['both']:>5} {row['only_a']:>6} "
                     f"{row['only_b']:>6} {row['neither']:>7} {100 * row['rate_a']:>6.1f} {100 * row['rate_b']:>6.1f} "
                     f"{100 * lo:>7.1f}..{100 * hi:<6.1f} {row['p_value']:>7.3g}  {row['verdict']}")
    lines.append(holm_text(cmp))
    lines.append(f"interval: {cmp['interval']}; test: {cmp['test']}; power for a "
                 f"{100 * cmp['difference']:.0f}-point difference at alpha {ALPHA}")
    return "\n".join(lines)
