"""Outcome categorization against hand-built traces: every row of the spec's Pick, Place, Open and Close tables
(appendix "Trajectory Annotation and Outcome Categorization") and of the Nav table, first satisfied row wins."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from aerobench.annotation import (
    CLOSE_MODES,
    MODE_TABLES,
    NAV_MODES,
    OPEN_MODES,
    PICK_MODES,
    PLACE_MODES,
    ArticulationChecks,
    Events,
    Evidence,
    OutcomeCode,
    Phase,
    categorize,
    first_satisfied,
)
from aerobench.annotation.events import CLEARANCE_M
from aerobench.annotation.modes import INIT_FAILED_MODE
from aerobench.envs.checks import FailureCause as C

from .test_events import fail_at, make_trace, on, succeed_at

SPEC_ROWS = {
    "pick": ("Successful grasp handoff", "Collision failure", "Object-drop failure", "Flight-envelope failure",
             "Other failure", "No-grasp truncation", "Grasp-without-lift truncation", "Incomplete-handoff truncation"),
    "place": ("Successful placement", "Collision-budget failure", "Flight-envelope failure", "Workspace failure",
              "Object-drop failure", "Unsupported-release failure", "Other failure", "No-alignment truncation",
              "No-support truncation", "No-release truncation", "Incomplete-completion truncation"),
    "open": ("Successful opening", "Airframe-contact failure", "Clearance-check failure", "Handle-approach failure",
             "Handle-pinch failure", "Handle-slip failure", "Opening-drive failure", "Opening-goal unmet",
             "Handle-release incomplete", "Arm-retraction incomplete", "Platform-settling incomplete",
             "Execution incomplete"),
    "close": ("Successful closing", "Airframe-contact failure", "Clearance-check failure", "Handle-approach failure",
              "Handle-pinch failure", "Handle-slip failure", "Closing-drive failure", "Closing-goal unmet",
              "Handle-release incomplete", "Arm-retraction incomplete", "Platform-settling incomplete",
              "Execution incomplete"),
    "nav": ("Successful navigation", "Collision failure", "Flight-envelope failure", "Object-drop failure",
            "Other failure", "No-progress truncation", "Unsettled truncation"),
}


def test_tables_are_the_spec_rows_in_order():
    for skill, rows in SPEC_ROWS.items():
        assert tuple(rule.name for rule in MODE_TABLES[skill]) == rows, skill
        assert all(rule.description for rule in MODE_TABLES[skill])


# ------------------------------------------------------------------------------------------------------------------
# Pick / Place / Nav: one hand-built trace per row -> (trace, truncated)
# ------------------------------------------------------------------------------------------------------------------
def pick(cause=None, grasp=None, lift=None, success=None, steps=20):
    trace = make_trace("pick", steps)
    if grasp is not None:
        on(trace, "is_grasped", grasp)
    if lift is not None:
        on(trace, "is_lifted", lift)
    if success is not None:
        succeed_at(trace, success)
    if cause is not None:
        fail_at(trace, steps - 3, cause)
    return trace, cause is None and success is None


def place(cause=None, align=None, support=None, release=None, clear=None, success=None, steps=30):
    trace = make_trace("place", steps)
    for key, t in (("is_aligned", align), ("is_support_contact", support), ("is_gripper_clear", clear)):
        if t is not None:
            on(trace, key, t)
    if release is not None:
        on(trace, "is_released", release, release + 1)
        on(trace, "release_registered", release)
    if success is not None:
        succeed_at(trace, success)
    if cause is not None:
        fail_at(trace, steps - 4, cause)
    return trace, cause is None and success is None


def nav(cause=None, reach=None, success=None, steps=20):
    trace = make_trace("nav", steps)
    if reach is not None:
        on(trace, "is_nav_reached", reach)
    if success is not None:
        succeed_at(trace, success)
    if cause is not None:
        fail_at(trace, steps - 2, cause)
    return trace, cause is None and success is None


ROW_CASES = [
    ("pick", "Successful grasp handoff", pick(grasp=3, lift=5, success=16)),
    ("pick", "Collision failure", pick(C.COLLISION, grasp=3)),
    ("pick", "Object-drop failure", pick(C.OBJECT_DROP, grasp=3, lift=5)),
    ("pick", "Flight-envelope failure", pick(C.TILT)),
    ("pick", "Flight-envelope failure", pick(C.LOW)),
    ("pick", "Flight-envelope failure", pick(C.HIGH)),
    ("pick", "Other failure", pick(C.WORKSPACE)),
    ("pick", "Other failure", pick(C.UNSUPPORTED_RELEASE)),
    ("pick", "No-grasp truncation", pick(lift=4)),  # lifted (knocked up) but never grasped
    ("pick", "Grasp-without-lift truncation", pick(grasp=3)),
    ("pick", "Incomplete-handoff truncation", pick(grasp=3, lift=5)),
    ("place", "Successful placement", place(align=3, support=6, release=8, clear=12, success=29)),
    ("place", "Collision-budget failure", place(C.COLLISION_FORCE, align=3)),
    ("place", "Flight-envelope failure", place(C.TILT)),
    ("place", "Flight-envelope failure", place(C.LOW)),
    ("place", "Flight-envelope failure", place(C.HIGH)),
    ("place", "Workspace failure", place(C.WORKSPACE)),
    ("place", "Object-drop failure", place(C.OBJECT_DROP, align=3)),
    ("place", "Unsupported-release failure", place(C.UNSUPPORTED_RELEASE, align=3, support=5)),
    ("place", "Other failure", place(C.COLLISION)),  # Pick's own row; Place's table has none for it
    ("place", "No-alignment truncation", place(support=5, release=7)),
    ("place", "No-support truncation", place(align=3, release=7)),
    ("place", "No-release truncation", place(align=3, support=6)),
    ("place", "Incomplete-completion truncation", place(align=3, support=6, release=8)),
    ("place", "Incomplete-completion truncation", place(align=3, support=6, release=8, clear=12)),
    ("nav", "Successful navigation", nav(reach=5, success=15)),
    ("nav", "Collision failure", nav(C.COLLISION, reach=5)),
    ("nav", "Flight-envelope failure", nav(C.TILT)),
    ("nav", "Object-drop failure", nav(C.OBJECT_DROP)),
    ("nav", "Other failure", nav(C.WORKSPACE)),
    ("nav", "No-progress truncation", nav()),
    ("nav", "Unsettled truncation", nav(reach=5)),
]


@pytest.mark.parametrize("skill, mode, case", ROW_CASES, ids=[f"{s}:{m}" for s, m, _ in ROW_CASES])
def test_pick_place_nav_rows(skill, mode, case):
    trace, truncated = case
    out = categorize(skill, trace, truncated)
    assert out.mode == mode
    expected_code = {"Successful": "S"}.get(mode.split()[0], "T" if truncated else "F")
    assert out.outcome == expected_code
    assert (out.cause != "") == (expected_code == "F")
    ending = np.flatnonzero(trace["success"] | (trace["fail_cause"] != 0))
    assert out.steps == (len(trace["success"]) if truncated else ending[0] + 1)


def test_every_row_has_a_trace():
    covered = {(skill, mode) for skill, mode, _ in ROW_CASES} | {(s, m) for s, m, _ in ART_CASES}
    assert covered == {(skill, rule.name) for skill, table in MODE_TABLES.items() for rule in table}


# ------------------------------------------------------------------------------------------------------------------
# Open / Close: checks J R A V N C and the terminal phase p
# ------------------------------------------------------------------------------------------------------------------
def articulation(skill, phase=Phase.DONE, fail=None, steps=16, **broken):
    """A trace whose terminal checks all hold except those in `broken` (J, R, A, V, N, C = False)."""
    trace = make_trace(skill, steps)
    trace["phase"][:] = Phase.DRIVE
    trace["phase"][-1] = phase
    trace["articulation_progress"] = np.linspace(0.0, 1.0, steps)
    for check, key in (("J", "is_goal_reached"), ("R", "is_released_handle"), ("A", "is_arm_retracted"),
                       ("V", "is_platform_stable")):
        on(trace, key, steps - 1, value=broken.get(check, True))
    if not broken.get("N", True):
        on(trace, "no_airframe_contact", 4, 5, False)  # one contact, mid-episode
    if not broken.get("C", True):
        on(trace, "min_clearance", 6, 7, CLEARANCE_M / 3)
    if fail is not None:
        fail_at(trace, steps - 1, fail)
    elif phase == Phase.DONE and not broken:
        succeed_at(trace, steps - 1)
    return trace, fail is None and not (phase == Phase.DONE and not broken)


def art_cases(skill, verb):
    return [
        (skill, f"Successful {verb}", articulation(skill)),
        (skill, "Airframe-contact failure", articulation(skill, Phase.DRIVE, C.AIRFRAME_CONTACT, N=False)),
        (skill, "Clearance-check failure", articulation(skill, Phase.DRIVE, C.CLEARANCE, C=False)),
        (skill, "Handle-approach failure", articulation(skill, Phase.FAIL_INSERT, C.PHASE, J=False)),
        (skill, "Handle-pinch failure", articulation(skill, Phase.FAIL_PINCH, C.PHASE, J=False)),
        (skill, "Handle-slip failure", articulation(skill, Phase.FAIL_SLIP, C.PHASE, J=False, R=False)),
        (skill, f"{verb.capitalize()}-drive failure", articulation(skill, Phase.FAIL_DRIVE, C.PHASE, J=False)),
        (skill, f"{verb.capitalize()}-goal unmet", articulation(skill, Phase.DRIVE, J=False, R=False, A=False)),
        (skill, "Handle-release incomplete", articulation(skill, Phase.RELEASE, R=False, A=False, V=False)),
        (skill, "Arm-retraction incomplete", articulation(skill, Phase.RETRACT, A=False, V=False)),
        (skill, "Platform-settling incomplete", articulation(skill, Phase.DONE, V=False)),
        (skill, "Execution incomplete", articulation(skill, Phase.RETRACT)),
    ]


ART_CASES = art_cases("open", "opening") + art_cases("close", "closing")


@pytest.mark.parametrize("skill, mode, case", ART_CASES, ids=[f"{s}:{m}" for s, m, _ in ART_CASES])
def test_open_close_rows(skill, mode, case):
    trace, truncated = case
    out = categorize(skill, trace, truncated)
    assert out.mode == mode
    assert out.checks is not None and out.diagnostics["terminal_phase"] == out.checks.phase.label


def test_open_close_successful_trace_is_outcome_s():
    out = categorize("open", *articulation("open"))
    assert (out.outcome, out.cause, out.checks.success) == ("S", "", True)
    assert all(out.diagnostics[f"check_{k}"] for k in "JRAVNC")


def test_airframe_contact_counts_at_any_step():
    trace, truncated = articulation("open", Phase.DONE)
    on(trace, "no_airframe_contact", 3, 4, False)  # the contact ends; the terminal value is True again
    trace["success"][:] = False
    assert categorize("open", trace, truncated=True).mode == "Airframe-contact failure"


def test_articulation_first_satisfied_row_wins():
    """Every check broken at once, then one row's cause repaired at a time: the mode walks down the table."""
    broken = dict(N=False, C=False, J=False, R=False, A=False, V=False)
    phases = [Phase.FAIL_INSERT, Phase.FAIL_PINCH, Phase.FAIL_SLIP, Phase.FAIL_DRIVE, Phase.DRIVE]
    expected = [rule.name for rule in OPEN_MODES[1:]]
    seen = []
    for check in ("N", "C"):
        seen.append(categorize("open", *articulation("open", phases[0], **broken)).mode)
        broken[check] = True
    for phase in phases:
        seen.append(categorize("open", *articulation("open", phase, **broken)).mode)
    for check in ("J", "R", "A", "V"):
        broken[check] = True
        seen.append(categorize("open", *articulation("open", Phase.RETRACT if check != "V" else Phase.DRIVE,
                                                     **broken)).mode)
    assert seen == expected


# ------------------------------------------------------------------------------------------------------------------
# Outcome semantics
# ------------------------------------------------------------------------------------------------------------------
def test_earlier_row_wins_when_several_hold():
    trace, _ = pick(C.COLLISION, grasp=3)
    out = categorize("pick", trace, truncated=False)
    evidence = Evidence(OutcomeCode(out.outcome), C.COLLISION, out.events)
    holding = [rule.name for rule in PICK_MODES if rule.predicate(evidence)]
    assert holding == ["Collision failure", "Other failure"] and out.mode == holding[0]


def test_primary_cause_is_the_first_latched():
    trace = make_trace("place", 12)
    trace["fail_cause"][4:8] = C.TILT
    trace["fail_cause"][8:] = C.OBJECT_DROP  # a later cause never replaces the first
    out = categorize("place", trace, truncated=False)
    assert (out.outcome, out.cause, out.mode) == ("F", "fail_tilt", "Flight-envelope failure")
    assert out.steps == 5 and out.events.t_fail == 4


@pytest.mark.parametrize("skill", ["pick", "place", "nav"])
def test_time_limit_truncation_with_events_is_never_a_failure(skill):
    trace = make_trace(skill, 30, is_grasped=False, is_object_supported=False)
    on(trace, "nontarget_contact_force", 5, 7, 4.0)  # contacts below the place budget, a near-miss, a slip
    on(trace, "airframe_contact_force", 6, 7, 3.0)
    on(trace, "min_obstacle_clearance", 8, 9, 0.0)
    on(trace, "tilt", 9, 10, 0.6)
    on(trace, "is_grasped", 2, 10)
    out = categorize(skill, trace, truncated=True)
    assert (out.outcome, out.cause) == ("T", "")
    assert out.mode.endswith("truncation")
    assert None not in (out.events.t_contact, out.events.t_airframe_contact, out.events.t_clearance)
    assert out.events.t_payload_loss == 10


def test_success_first_then_failure_stays_success():
    """Recorded with ignore_terminations: the episode ended at its success; later steps are ignored."""
    trace, _ = pick(grasp=2, lift=3, success=6)
    fail_at(trace, 10, C.TILT)
    out = categorize("pick", trace, truncated=True)
    assert (out.outcome, out.mode, out.steps) == ("S", "Successful grasp handoff", 7)
    assert out.events.t_tilt is None


def test_failure_on_the_success_step_is_a_failure():
    trace = fail_at(succeed_at(make_trace("nav", 10), 5), 5, C.COLLISION)
    assert categorize("nav", trace, truncated=False).outcome == "F"


def test_trace_without_an_ending_is_rejected():
    with pytest.raises(ValueError, match="cut short"):
        categorize("pick", make_trace("pick", 10), truncated=False)


def test_init_failure_is_recorded_separately():
    trace = make_trace("pick", 3, init_failed=True)
    out = categorize("pick", trace, truncated=True)
    assert (out.outcome, out.mode, out.cause, out.steps) == ("I", INIT_FAILED_MODE, "", 0)
    assert categorize("pick", {}, truncated=True, init_failed=True).outcome == "I"
    assert categorize("pick", make_trace("pick", 3), truncated=True, init_failed=False).outcome == "T"


def test_torch_trace():
    trace, truncated = pick(grasp=3, lift=5, success=16)
    out = categorize("pick", {k: torch.as_tensor(v) for k, v in trace.items()}, truncated)
    assert out.mode == "Successful grasp handoff"


def test_diagnostics_are_retained():
    trace, truncated = place(C.COLLISION_FORCE, align=3)
    trace["tilt"] = np.linspace(0.0, 0.2, 30)
    trace["collision_impulse"] = np.linspace(0.0, 0.6, 30)
    out = categorize("place", trace, truncated)
    d = out.diagnostics
    assert d["max_tilt_rad"] == pytest.approx(0.2 * 26 / 29)  # up to the failing step
    assert d["max_collision_impulse_ns"] == pytest.approx(0.6 * 26 / 29)
    for key in ("min_obstacle_clearance_m", "max_nontarget_contact_force_n", "min_goal_distance_m", "min_altitude_m"):
        assert key in d


def test_phase_codes_and_labels():
    labels = ["approach", "pinch", "drive", "release", "retract", "done", "fail_insert", "fail_pinch", "fail_slip",
              "fail_drive"]
    assert [Phase(i).label for i in range(10)] == labels
    assert [p for p in Phase if p.failed] == [Phase.FAIL_INSERT, Phase.FAIL_PINCH, Phase.FAIL_SLIP, Phase.FAIL_DRIVE]


# ------------------------------------------------------------------------------------------------------------------
# Tables are exhaustive: every possible evidence matches a row
# ------------------------------------------------------------------------------------------------------------------
def test_pick_place_nav_tables_are_exhaustive():
    event_sets = [Events(**dict(zip(("t_g", "t_l", "t_o", "t_d", "t_r", "t_reach"), times)))
                  for times in itertools.product((None, 1), repeat=6)]
    for table in (PICK_MODES, PLACE_MODES, NAV_MODES):
        for code, cause, events in itertools.product(("S", "F", "T"), list(C)[1:], event_sets):
            rule = first_satisfied(table, Evidence(OutcomeCode(code), cause if code == "F" else C.NONE, events))
            assert rule.name.startswith({"S": "Successful", "F": "", "T": ""}[code])


def test_articulation_tables_are_exhaustive():
    for table in (OPEN_MODES, CLOSE_MODES):
        for values in itertools.product((True, False), repeat=6):
            for phase in Phase:
                checks = ArticulationChecks(*values, phase=phase)
                rule = first_satisfied(table, Evidence(OutcomeCode.TRUNCATION, C.NONE, Events(), checks))
                assert (rule is table[0]) == (all(values) and phase == Phase.DONE)
