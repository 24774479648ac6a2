"""Results: per-episode records -> a versioned results JSON (per skill x object success, SE, Wilson, modes).

The spec's table cell is "success % +- binomial SE" over one skill-object pair's evaluation episodes; "Mean S.R." is
the unweighted mean over the skill-object pairs. Initialization failures (starts the planner or env rejected) are
counted apart and never enter n. Chain runs also get per-stage conditional success from their segments, so error
propagation across skills is visible.
"""

from __future__ import annotations

import datetime
import json
import math
from collections import Counter
from collections.abc import Iterable, Mapping
from pathlib import Path

from .. import __version__
from ..envs.tasks import SKILLS
from .stats import standard_error, wilson_interval

RESULTS_FORMAT = "aerobench-results"
RESULTS_VERSION = 1
# The input tier of a policy whose results name none (aerobench.tiers): the expert and random read what they always
# read; a learned policy's tier is its checkpoint's (eval asks the policy), unknown where only records are at hand.
DEFAULT_TIERS = {"expert": "privileged", "random": "none"}
UNKNOWN_TIER = "unknown"


def rate_fields(successes: int, n: int) -> dict:
    """A cell's success statistics: n, successes, rate, binomial SE, Wilson 95%."""
    lo, hi = wilson_interval(successes, n)
    return {"n": n, "successes": successes, "success_rate": successes / n if n else 0.0,
            "se": standard_error(successes, n), "wilson95": [lo, hi]}


def failure_modes(modes: Mapping[str, int]) -> dict[str, int]:
    """The counts of the modes that are not a success (every success mode is named "Successful ..."), most
    frequent first."""
    return dict(sorted(((m, k) for m, k in modes.items() if not m.startswith("Successful")), key=lambda mk: -mk[1]))


def over_all_cells(results: Mapping) -> dict:
    """One results file as one number: successes and n summed over its cells, their rate statistics and mode counts
    (for a one-skill, one-object comparison; the table's Mean S.R. is the mean over cells instead)."""
    cells = results["cells"]
    modes = sum((Counter(c["modes"]) for c in cells), Counter())
    return {**rate_fields(sum(c["successes"] for c in cells), sum(c["n"] for c in cells)), "modes": dict(modes)}


def _cell(rows: list[Mapping]) -> dict:
    executed = [r for r in rows if r["outcome"] != "I"]
    return {
        **rate_fields(sum(r["outcome"] == "S" for r in executed), len(executed)),
        "init_failures": len(rows) - len(executed),
        "outcomes": dict(Counter(r["outcome"] for r in executed)),
        "modes": dict(Counter(r["mode"] for r in executed)),
        "causes": dict(Counter(r["cause"] for r in executed if r["cause"])),
        # per episode (plan index, seed, outcome), so two runs on the same starts can be compared pairwise
        "episodes": [[int(r["episode_index"]), r.get("seed"), r["outcome"]] for r in rows],
        "failure_analysis": failure_summary(executed),
        # median episode seconds of the successes (records' duration_s; None where none succeeded or none say)
        "time_to_success_s": median([r.get("duration_s") for r in executed if r["outcome"] == "S"]),
        **flight_summary(executed),
    }


def flight_summary(rows: list[Mapping]) -> dict:
    """How hard the airframe was thrown about: over the episodes whose records carry it, the median and the largest of
    each episode's maximum tilt, in degrees, and the episodes' values; where recorded, the same for the share of its
    control steps at which a rotor's thrust was clipped (`annotation.events` diagnostics; a condition's
    effect beside success, pooled over cells by the robustness view)."""
    tilts = [math.degrees(d["max_tilt_rad"]) for r in rows
             if (d := r.get("diagnostics") or {}).get("max_tilt_rad") is not None]
    if not tilts:
        return {}
    flight = {"median_max_tilt_deg": median(tilts), "max_tilt_deg": max(tilts),
              "max_tilt_deg_per_episode": [round(t, 2) for t in tilts]}
    # the share of each episode's control steps with a clipped rotor (records of `rotor_statistics` runs)
    shares = [d["rotor_saturated_steps"] / r["steps"] for r in rows
              if (d := r.get("diagnostics") or {}).get("rotor_saturated_steps") is not None and r.get("steps")]
    if shares:
        flight |= {"median_saturated_share": median(shares), "saturated_episodes": sum(s > 0 for s in shares),
                   "saturated_share_per_episode": [round(s, 4) for s in shares]}
    return {"flight": flight}


ROTATION_BINS_DEG = (2.0, 16.0)  # spec Fig. "Grasp quality": no grasp under 2 deg is lost; loss rates above 16 deg


def _stage(row: Mapping, skill: str) -> tuple[str, dict] | None:
    """(outcome, diagnostics) of `skill` in a row: the row itself, or its chain segment of that skill."""
    if row["skill"] == skill:
        return row["outcome"], row.get("diagnostics") or {}
    for seg in row.get("segments") or ():
        if seg["skill"] == skill:
            return seg["outcome"], seg.get("diagnostics") or {}
    return None


def median(values: list[float]) -> float | None:
    values = sorted(v for v in values if v is not None)
    if not values:
        return None
    mid = len(values) // 2
    return values[mid] if len(values) % 2 else (values[mid - 1] + values[mid]) / 2


def failure_summary(rows: list[Mapping]) -> dict:
    """The spec's failure-analysis quantities over executed episodes (`annotation.failure_analysis` per episode):
    pick mechanisms, handoff rotation, release speed, transport grasp losses by mechanism and by handoff rotation."""
    out: dict = {}  # a stage is summarized only when its episodes carry the diagnostics (older records do not)
    picks = [s for r in rows if (s := _stage(r, "pick")) and "speed_at_finger_contact_mps" in s[1]]
    if picks:
        failed = [d for outcome, d in picks if outcome != "S"]
        out["pick"] = {
            "median_speed_at_finger_contact_mps": median([d.get("speed_at_finger_contact_mps") for _, d in picks]),
            "median_handoff_rotation_deg": median([d.get("handoff_rotation_deg") for _, d in picks]),
            "failures": len(failed),
            "failures_knocked_object": sum(bool(d.get("knocked_object")) for d in failed),
            "failures_hit_scene": sum(bool(d.get("hit_scene")) and not d.get("knocked_object") for d in failed),
        }
    places = [s[1] for r in rows if (s := _stage(r, "place")) and "speed_at_release_mps" in s[1]]
    if places:
        out["place"] = {"median_speed_at_release_mps": median([d.get("speed_at_release_mps") for d in places])}
    transports = [(r, s[1]) for r in rows
                  if r.get("segments") and (s := _stage(r, "nav")) and "grasp_loss_mechanism" in s[1]]
    if transports:
        mechanisms = Counter(d.get("grasp_loss_mechanism") for _, d in transports if d.get("grasp_loss_mechanism"))
        bins: dict[str, list[int]] = {}
        lo, hi = ROTATION_BINS_DEG
        for row, d in transports:
            rotation = (_stage(row, "pick") or ("", {}))[1].get("handoff_rotation_deg")
            if rotation is None:
                continue
            name = f"<{lo:g}" if rotation < lo else (f"{lo:g}-{hi:g}" if rotation <= hi else f">{hi:g}")
            lost_total = bins.setdefault(name, [0, 0])
            lost_total[0] += bool(d.get("grasp_loss_mechanism"))
            lost_total[1] += 1
        out["transport"] = {"grasp_losses": dict(mechanisms), "losses_by_handoff_rotation_deg": bins}
    return out


def _chain_stages(rows: list[Mapping]) -> list[dict]:
    """Per stage: episodes that reached it, of which succeeded, and the conditional rate."""
    stages: dict[int, dict] = {}
    for row in rows:
        if row["outcome"] == "I":
            continue
        for seg in row.get("segments") or ():
            s = stages.setdefault(seg["stage"], {"stage": seg["stage"], "skill": seg["skill"], "reached": 0, "successes": 0,
                                                 "modes": Counter()})
            s["reached"] += 1
            s["successes"] += seg["outcome"] == "S"
            s["modes"][seg["mode"]] += 1
    out = []
    for stage in sorted(stages):
        s = stages[stage]
        n, k = s["reached"], s["successes"]
        out.append({**s, "modes": dict(s["modes"]), "conditional_success": k / n if n else 0.0,
                    "se": standard_error(k, n)})
    return out


def summarize(records: Iterable[Mapping], provenance: Mapping | None = None, label: str | None = None,
              inputs: str | None = None) -> dict:
    """A results document from episode-record rows (dicts as in records.jsonl) of one policy on one setting;
    `inputs`: the policy's input tier (`aerobench.tiers`; unknown for records of no known policy)."""
    rows = list(records)
    if not rows:
        raise ValueError("no episode records to summarize")
    settings = {r["setting"] for r in rows}
    policies = {r["policy"] for r in rows}
    if len(settings) != 1 or len(policies) != 1:
        raise ValueError(f"one results file holds one policy on one setting; got settings {sorted(settings)}, "
                         f"policies {sorted(policies)}")
    groups: dict[tuple[str, str], list] = {}
    for row in sorted(rows, key=lambda r: r["episode_index"]):
        groups.setdefault((row["skill"], row["object"]), []).append(row)
    skill_rank = {s: i for i, s in enumerate(SKILLS)}
    cells = [
        {"skill": skill, "object": obj, **_cell(group)}
        for (skill, obj), group in sorted(groups.items(), key=lambda kv: (skill_rank.get(kv[0][0], 99), kv[0][0]))
    ]
    scored = [c for c in cells if c["n"]]
    per_skill = {}
    for cell in scored:
        per_skill.setdefault(cell["skill"], []).append(cell["success_rate"])
    chains = {}
    for (skill, _), group in groups.items():
        if any(r.get("segments") for r in group):
            chains.setdefault(skill, []).extend(group)
    policy = policies.pop()
    return {
        "format": RESULTS_FORMAT,
        "version": RESULTS_VERSION,
        "aerobench_version": __version__,
        "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "setting": settings.pop(),
        "policy": policy,
        "inputs": inputs or DEFAULT_TIERS.get(policy, UNKNOWN_TIER),
        "label": label or policy,
        "provenance": dict(provenance or {}),
        "episodes": len(rows),
        "cells": cells,
        "skill_mean_sr": {s: sum(v) / len(v) for s, v in per_skill.items()},
        "mean_sr": sum(c["success_rate"] for c in scored) / len(scored) if scored else 0.0,
        "chains": {name: _chain_stages(group) for name, group in chains.items()},
    }


def write_results(path: str | Path, results: Mapping) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    tmp.replace(path)
    return path


def load_results(path: str | Path) -> dict:
    """Read a results file, refusing other formats and other results versions with a one-line reason."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no results file at {path} (aerobench eval writes DIR/results.json)")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path} is not JSON ({e.msg} at line {e.lineno})") from None
    if not isinstance(data, dict) or data.get("format") != RESULTS_FORMAT:
        raise ValueError(f"{path} is not an aerobench results file (no \"format\": \"{RESULTS_FORMAT}\")")
    if data.get("version") != RESULTS_VERSION:
        raise ValueError(f"{path} is results version {data.get('version')!r} (written by aerobench "
                         f"{data.get('aerobench_version', '?')}); this aerobench reads version {RESULTS_VERSION}: "
                         f"re-run aerobench eval or use the matching aerobench version")
    return data
