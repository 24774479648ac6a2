"""Skill segments of long-horizon (AeroSequential-v1) rollouts, and the Place handoff-eligibility check.

Spec Sec. "Event Annotation for Aerial Manipulation" and appendix "Demonstration Selection and Skill Attribution":
skill-level outcomes are kept next to the parent rollout's; a completed skill stays valid (S) if a later stage
fails, a stage active when the episode fails is F (also when its own success lands on the failing step: concurrent
physical failures stay failures), a stage active at the time limit is T, and stages never reached get no segment.
Parent ids and event boundaries (`start`, `end`) tie each segment to its rollout. Place segments must begin from an
eligible held state outside the destination support region.

Convention: `subtask_index[t]` is the stage pointer after control step t, as AeroSequential-v1 reports it (it
advances the pointer on the step its active stage succeeds). So stage k is active during step t iff
`subtask_index[t - 1] == k` (stage 0 at t = 0), and stage k succeeds on the first step with `subtask_index > k`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .events import Signals, check_skill, signal, slice_signals, trace_length
from .modes import Outcome, categorize, episode_end

HANDOFF_GOAL_DISTANCE_M = 0.10  # the Place goal region's radius: a handoff starts farther than this from the goal


@dataclass(frozen=True)
class Segment:
    """One chain stage of a parent rollout; steps [start, end) of the parent trace, events relative to `start`."""

    parent_id: str
    stage: int
    skill: str
    start: int
    end: int  # exclusive
    outcome: Outcome
    eligible: bool = True
    eligibility: str = ""

    def to_dict(self) -> dict:
        """JSON-ready form, as `EpisodeRecord.segments` stores it."""
        o = self.outcome
        return {
            "parent_id": self.parent_id, "stage": self.stage, "skill": self.skill, "start": self.start,
            "end": self.end, "steps": o.steps, "outcome": str(o.outcome), "mode": o.mode, "cause": o.cause,
            "events": o.events.as_dict(), "eligible": self.eligible, "eligibility": self.eligibility,
            "diagnostics": dict(o.diagnostics),
        }


def active_stages(subtask_index: np.ndarray) -> np.ndarray:
    """The stage active during each step `(T,)`, from the after-step pointer (see the module docstring)."""
    pointer = np.asarray(subtask_index).astype(int)
    if np.any(np.diff(pointer) < 0):
        raise ValueError(f"subtask_index goes backwards ({pointer.tolist()}); one trace must hold one episode")
    return np.concatenate([[0], pointer[:-1]]).astype(int)


def cut_segments(
    signals: Signals,
    chain: Sequence[str],
    truncated: bool,
    parent_id: str = "",
    init_failed: bool | None = None,
) -> list[Segment]:
    """Segments of one sequential rollout, one per stage that was active, each with its own `categorize` outcome.

    `chain`: the stages' skill names in order; `truncated`: the parent reached its time limit; `init_failed`
    (default: the trace's `init_failed` at its first step): no segments, the parent is recorded separately.
    """
    for skill in chain:
        check_skill(skill)
    if init_failed is None:
        init_failed = "init_failed" in signals and trace_length(signals) > 0 and bool(signal(signals, "init_failed")[0])
    if init_failed or trace_length(signals) == 0:
        return []
    n_steps = episode_end(signals)
    episode = slice_signals(signals, 0, n_steps)
    pointer = signal(episode, "subtask_index").astype(int)
    if pointer.min() < 0 or pointer.max() > len(chain):
        raise ValueError(f"subtask_index outside [0, {len(chain)}] for a {len(chain)}-stage chain")
    active = active_stages(pointer)
    segments = []
    for stage, skill in enumerate(chain):
        steps = np.flatnonzero(active == stage)
        if not steps.size:  # never reached
            continue
        start, end = int(steps[0]), int(steps[-1]) + 1
        part = slice_signals(episode, start, end)
        part["success"] = pointer[start:end] > stage  # the env's own "success" is the whole chain's
        outcome = categorize(skill, part, truncated=truncated and end == n_steps, init_failed=False)
        segment = Segment(parent_id, stage, skill, start, end, outcome)
        eligible, reason = is_eligible_handoff(segment, episode)
        segments.append(replace(segment, eligible=eligible, eligibility=reason))
    return segments


def is_eligible_handoff(segment: Segment, signals: Signals) -> tuple[bool, str]:
    """(eligible, reason) of a segment's starting state; `signals` is the parent trace.

    A Place segment must start held (`is_grasped`) outside the destination support region: no support contact and
    more than HANDOFF_GOAL_DISTANCE_M from the goal (spec "Demonstration Selection and Skill Attribution"). Other
    skills carry no handoff condition.
    """
    if segment.skill != "place":
        return True, f"no handoff condition for {segment.skill}"
    t = segment.start
    if not bool(signal(signals, "is_grasped")[t]):
        return False, "object not held at the segment start"
    if bool(signal(signals, "is_support_contact")[t]):
        return False, "object already in support contact at the destination at the segment start"
    distance = float(signal(signals, "goal_distance")[t])
    if not distance > HANDOFF_GOAL_DISTANCE_M:
        return False, f"object {distance:.3f} m from the goal at the segment start (needs > {HANDOFF_GOAL_DISTANCE_M} m)"
    return True, "held outside the destination support region"
