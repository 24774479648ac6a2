"""Outcomes (S / F / T) and diagnostic modes: the spec's outcome tables as ordered rules.

Spec appendix "Trajectory Annotation and Outcome Categorization", Tables "Outcome categories for Pick / Place /
Open / Close": within each table the first satisfied row is the primary reported mode, and all underlying
diagnostic signals are retained (`Outcome.diagnostics`). Nav has no table in the spec; `NAV_MODES` follows the
Pick table's shape. Initialization failures are recorded separately (outcome "I"), never as executed trajectories.

Outcome semantics: S once success is reached; F once a failure is latched (`fail_cause != 0`), with the FIRST
latched cause as the primary cause (a failure latched on the same step as a success wins: a concurrent physical
failure stays a failure); T when the episode reached its time limit with neither. A time-limit truncation is never
relabelled as a failure. Steps after the episode ended (first S or F) are ignored, so traces recorded with
`ignore_terminations` categorize like terminated ones.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum

from ..envs.checks import FailureCause, Phase
from .events import (
    ARTICULATION_SKILLS,
    CLEARANCE_M,
    Events,
    Signals,
    check_skill,
    extract_events,
    first_time,
    signal,
    slice_signals,
    summarize,
    trace_length,
)
from .failure_analysis import failure_analysis


class OutcomeCode(StrEnum):
    SUCCESS = "S"
    FAILURE = "F"
    TRUNCATION = "T"
    INIT_FAILED = "I"  # spec: "Initialization failures and infeasible starts are recorded separately"


INIT_FAILED_MODE = "Initialization failure"


@dataclass(frozen=True)
class ArticulationChecks:
    """The spec's Open/Close checks: J goal, R handle released, A arm retracted, V platform stable (terminal values),
    N no airframe contact at any step, C clearance >= CLEARANCE_M throughout, and the terminal phase p."""

    J: bool
    R: bool
    A: bool
    V: bool
    N: bool
    C: bool
    phase: Phase

    @property
    def success(self) -> bool:
        """S_art = J and R and A and V and N and C and [p = done]."""
        return self.J and self.R and self.A and self.V and self.N and self.C and self.phase == Phase.DONE


def articulation_checks(signals: Signals) -> ArticulationChecks:
    """Checks of an Open / Close trace (at least one step)."""

    def last(key: str) -> bool:
        return bool(signal(signals, key)[-1])

    return ArticulationChecks(
        J=last("is_goal_reached"),
        R=last("is_released_handle"),
        A=last("is_arm_retracted"),
        V=last("is_platform_stable"),
        # "at least one airframe contact is recorded": any step, so an unlatched signal cannot hide a contact
        N=bool(signal(signals, "no_airframe_contact").astype(bool).all()),
        C=bool(signal(signals, "min_clearance").min() >= CLEARANCE_M),
        phase=Phase(int(signal(signals, "phase")[-1])),
    )


@dataclass(frozen=True)
class Evidence:
    """What a mode row reads: outcome, primary cause, event times and (Open / Close) the checks."""

    outcome: OutcomeCode
    cause: FailureCause
    events: Events
    checks: ArticulationChecks | None = None


@dataclass(frozen=True)
class ModeRule:
    name: str
    description: str
    predicate: Callable[[Evidence], bool]


# Row predicates, named so that the tables below read like the spec's.
def _success(x: Evidence) -> bool:
    return x.outcome == OutcomeCode.SUCCESS


def _failed(*causes: FailureCause) -> Callable[[Evidence], bool]:
    """F with a primary cause among `causes` (any cause when none are given)."""
    return lambda x: x.outcome == OutcomeCode.FAILURE and (not causes or x.cause in causes)


def _truncated(when: Callable[[Events], bool] = lambda e: True) -> Callable[[Evidence], bool]:
    return lambda x: x.outcome == OutcomeCode.TRUNCATION and when(x.events)


ENVELOPE = (FailureCause.TILT, FailureCause.LOW, FailureCause.HIGH)

PICK_MODES: tuple[ModeRule, ...] = (
    ModeRule("Successful grasp handoff", "S: the Pick completion condition is satisfied.", _success),
    ModeRule("Collision failure", "F and c = collision: unintended contact with non-target scene geometry.",
             _failed(FailureCause.COLLISION)),
    ModeRule("Object-drop failure", "F and c = fail_object_drop: the object violates the minimum-height condition.",
             _failed(FailureCause.OBJECT_DROP)),
    ModeRule("Flight-envelope failure", "F and c in {fail_tilt, fail_low, fail_high}: attitude or altitude envelope.",
             _failed(*ENVELOPE)),
    ModeRule("Other failure", "F with any remaining cause, including workspace violations.", _failed()),
    ModeRule("No-grasp truncation", "T and t_g = inf: no grasp is observed before timeout.",
             _truncated(lambda e: e.t_g is None)),
    ModeRule("Grasp-without-lift truncation", "T, t_g < inf, t_l = inf: grasped, lift threshold never reached.",
             _truncated(lambda e: e.t_g is not None and e.t_l is None)),
    ModeRule("Incomplete-handoff truncation", "T, t_g < inf, t_l < inf: the final handoff condition is not completed.",
             _truncated(lambda e: e.t_g is not None and e.t_l is not None)),
)

PLACE_MODES: tuple[ModeRule, ...] = (
    ModeRule("Successful placement", "S: placement, release, clearance and sustained platform stability.", _success),
    ModeRule("Collision-budget failure", "F, c = fail_collision_force: accumulated collision force over budget.",
             _failed(FailureCause.COLLISION_FORCE)),
    ModeRule("Flight-envelope failure", "F, c in {fail_tilt, fail_low, fail_high}.", _failed(*ENVELOPE)),
    ModeRule("Workspace failure", "F, c = fail_workspace: the UAV leaves the workspace boundary.",
             _failed(FailureCause.WORKSPACE)),
    ModeRule("Object-drop failure", "F, c = fail_object_drop: object below the floor or support-relative threshold.",
             _failed(FailureCause.OBJECT_DROP)),
    ModeRule("Unsupported-release failure", "F, c = fail_unsupported_release: grasp lost without support evidence.",
             _failed(FailureCause.UNSUPPORTED_RELEASE)),
    ModeRule("Other failure", "F with any remaining cause, including non-finite policy features.", _failed()),
    ModeRule("No-alignment truncation", "T and t_o = inf: never within the horizontal alignment tolerance.",
             _truncated(lambda e: e.t_o is None)),
    ModeRule("No-support truncation", "T, t_o < inf, t_d = inf: aligned, no support contact in the goal region.",
             _truncated(lambda e: e.t_o is not None and e.t_d is None)),
    ModeRule("No-release truncation", "T, t_o, t_d < inf, t_r = inf: the release event is not observed.",
             _truncated(lambda e: e.t_o is not None and e.t_d is not None and e.t_r is None)),
    ModeRule("Incomplete-completion truncation", "Remaining T: placement, clearance or stability not all satisfied.",
             _truncated()),
)

NAV_MODES: tuple[ModeRule, ...] = (  # not in the spec; the Pick table's shape
    ModeRule("Successful navigation", "S: within reach of the target and settled for the required steps.", _success),
    ModeRule("Collision failure", "F and c = collision: unintended contact with scene geometry.",
             _failed(FailureCause.COLLISION)),
    ModeRule("Flight-envelope failure", "F and c in {fail_tilt, fail_low, fail_high}.", _failed(*ENVELOPE)),
    ModeRule("Object-drop failure", "F and c = fail_object_drop: the carried object is lost.",
             _failed(FailureCause.OBJECT_DROP)),
    ModeRule("Other failure", "F with any remaining cause, including workspace violations.", _failed()),
    ModeRule("No-progress truncation", "T and t_reach = inf: never within reach of the target.",
             _truncated(lambda e: e.t_reach is None)),
    ModeRule("Unsettled truncation", "T and t_reach < inf: reached the target but never settled there.",
             _truncated(lambda e: e.t_reach is not None)),
)


def _check(test: Callable[[ArticulationChecks], bool]) -> Callable[[Evidence], bool]:
    return lambda x: x.checks is not None and test(x.checks)


def _articulation_modes(verb: str, goal: str) -> tuple[ModeRule, ...]:
    """Spec Tables "Outcome categories for Open / Close" (identical rows; `verb` = opening / closing)."""
    return (
        ModeRule(f"Successful {verb}", f"S_art: the {verb} threshold and all completion checks are satisfied.",
                 _check(lambda c: c.success)),
        ModeRule("Airframe-contact failure", "not N: at least one airframe contact is recorded.",
                 _check(lambda c: not c.N)),
        ModeRule("Clearance-check failure", "not C: the minimum sampled clearance is below 0.03 m.",
                 _check(lambda c: not c.C)),
        ModeRule("Handle-approach failure", "p = fail_insert: the approach misses its target within the phase limit.",
                 _check(lambda c: c.phase == Phase.FAIL_INSERT)),
        ModeRule("Handle-pinch failure", "p = fail_pinch: the required finger-contact condition is not satisfied.",
                 _check(lambda c: c.phase == Phase.FAIL_PINCH)),
        ModeRule("Handle-slip failure", f"p = fail_slip: handle contact is lost before the {verb} goal is reached.",
                 _check(lambda c: c.phase == Phase.FAIL_SLIP)),
        ModeRule(f"{verb.capitalize()}-drive failure", "p = fail_drive: the drive phase exceeds its time limit.",
                 _check(lambda c: c.phase == Phase.FAIL_DRIVE)),
        ModeRule(f"{verb.capitalize()}-goal unmet", f"not J: the final articulation position misses {goal}.",
                 _check(lambda c: not c.J)),
        ModeRule("Handle-release incomplete", "not R: the terminal release condition is not satisfied.",
                 _check(lambda c: not c.R)),
        ModeRule("Arm-retraction incomplete", "not A: the arm does not return to the prescribed rest pose.",
                 _check(lambda c: not c.A)),
        ModeRule("Platform-settling incomplete", "not V: terminal velocity exceeds the stability threshold.",
                 _check(lambda c: not c.V)),
        ModeRule("Execution incomplete", "Remaining unsuccessful cases with p != done.",
                 _check(lambda c: c.phase != Phase.DONE)),
    )


OPEN_MODES = _articulation_modes("opening", "q >= alpha_a")
CLOSE_MODES = _articulation_modes("closing", "q <= 0.01")

MODE_TABLES: Mapping[str, tuple[ModeRule, ...]] = {
    "pick": PICK_MODES, "place": PLACE_MODES, "nav": NAV_MODES, "open": OPEN_MODES, "close": CLOSE_MODES,
}


def first_satisfied(rules: tuple[ModeRule, ...], evidence: Evidence) -> ModeRule:
    """The table's first row whose predicate holds."""
    for rule in rules:
        if rule.predicate(evidence):
            return rule
    raise ValueError(f"no mode row matches {evidence}")


@dataclass(frozen=True)
class Outcome:
    """One trajectory's (or segment's) annotation."""

    skill: str
    outcome: OutcomeCode
    cause: str  # FailureCause label of the first latched cause; "" unless F
    mode: str
    events: Events
    steps: int  # control steps of the episode (up to and including its ending step)
    diagnostics: Mapping[str, float | int | bool | str | None] = field(default_factory=dict)
    checks: ArticulationChecks | None = None


def episode_end(signals: Signals) -> int:
    """Number of steps the episode ran: through its first success or latched failure, else the whole trace."""
    ends = [t for t in (first_time(signal(signals, "success")), first_time(signal(signals, "fail_cause") != 0))
            if t is not None]
    return min(ends) + 1 if ends else trace_length(signals)


def outcome_code(signals: Signals, truncated: bool) -> tuple[OutcomeCode, FailureCause]:
    """S / F / T and the primary (first latched) failure cause of an executed trajectory."""
    causes = signal(signals, "fail_cause")
    t_fail = first_time(causes != 0)
    t_success = first_time(signal(signals, "success"))
    if t_fail is not None and (t_success is None or t_fail <= t_success):
        return OutcomeCode.FAILURE, FailureCause(int(causes[t_fail]))
    if t_success is not None:
        return OutcomeCode.SUCCESS, FailureCause.NONE
    if truncated:
        return OutcomeCode.TRUNCATION, FailureCause.NONE
    raise ValueError("the trace ends without success, a latched failure or the time limit; was it cut short?")


def categorize(skill: str, signals: Signals, truncated: bool, init_failed: bool | None = None) -> Outcome:
    """Outcome, primary cause, mode (first satisfied row of `MODE_TABLES[skill]`), events and diagnostics.

    `truncated`: the episode reached its time limit. `init_failed`: no feasible start (default: the trace's
    `init_failed` signal at its first step, False without one); such episodes get outcome "I".
    """
    check_skill(skill)
    if init_failed is None:
        init_failed = "init_failed" in signals and trace_length(signals) > 0 and bool(signal(signals, "init_failed")[0])
    if init_failed:
        return Outcome(skill, OutcomeCode.INIT_FAILED, "", INIT_FAILED_MODE, Events(), 0)
    if trace_length(signals) == 0:
        raise ValueError("an executed episode needs at least one recorded control step")
    steps = episode_end(signals)
    episode = slice_signals(signals, 0, steps)
    code, cause = outcome_code(episode, truncated)
    events = extract_events(skill, episode)
    checks = articulation_checks(episode) if skill in ARTICULATION_SKILLS else None
    mode = first_satisfied(MODE_TABLES[skill], Evidence(code, cause, events, checks))
    diagnostics: dict[str, float | int | bool | str | None] = summarize(skill, episode)
    diagnostics.update(failure_analysis(skill, episode))
    if checks is not None:
        diagnostics.update({f"check_{k}": getattr(checks, k) for k in "JRAVNC"}, terminal_phase=checks.phase.label)
    return Outcome(skill, code, cause.label, mode.name, events, steps, diagnostics, checks)

