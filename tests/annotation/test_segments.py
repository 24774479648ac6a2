"""Skill segments of chained rollouts and the Place handoff check (spec "Demonstration Selection and Skill
Attribution")."""

from __future__ import annotations

import json

import pytest

from aerobench.annotation import cut_segments, is_eligible_handoff
from aerobench.annotation.segments import HANDOFF_GOAL_DISTANCE_M, active_stages
from aerobench.envs.checks import FailureCause

from .test_events import fail_at, make_trace, on, succeed_at

CHAIN = ("pick", "nav", "place")


def chain_trace(steps: int = 20) -> dict:
    """Pick active on steps 0-5 (succeeds on 5), Nav from step 6; nothing latched yet."""
    trace = make_trace(CHAIN, steps, is_grasped=False, is_object_supported=True)
    on(trace, "is_grasped", 2)
    on(trace, "is_object_supported", 3, value=False)
    on(trace, "is_lifted", 3, 6)
    on(trace, "subtask_index", 5, value=1)  # the env advances the pointer on the step the stage succeeds
    return trace


def test_active_stage_follows_the_after_step_pointer():
    assert active_stages([0, 0, 1, 1, 2, 3]).tolist() == [0, 0, 0, 1, 1, 2]
    with pytest.raises(ValueError, match="backwards"):
        active_stages([0, 1, 0])


def test_stage_two_fails():
    trace = chain_trace()
    fail_at(trace, 11, FailureCause.COLLISION)
    on(trace, "subtask_index", 15, value=2)  # recorded past the end (ignore_terminations): ignored
    segments = cut_segments(trace, CHAIN, truncated=False, parent_id="ep-7")
    assert [(s.stage, s.skill, s.start, s.end) for s in segments] == [(0, "pick", 0, 6), (1, "nav", 6, 12)]
    pick, nav = segments
    assert (pick.outcome.outcome, pick.outcome.mode) == ("S", "Successful grasp handoff")  # stays valid
    assert (pick.outcome.events.t_g, pick.outcome.events.t_l, pick.outcome.steps) == (2, 3, 6)
    assert (nav.outcome.outcome, nav.outcome.cause, nav.outcome.mode) == ("F", "collision", "Collision failure")
    assert nav.outcome.events.t_fail == 5  # relative to the segment's first step
    assert all(s.parent_id == "ep-7" for s in segments)


def test_full_chain_and_events_relative_to_the_segment():
    trace = chain_trace()
    on(trace, "is_nav_reached", 9)
    on(trace, "subtask_index", 11, value=2)
    on(trace, "is_aligned", 14)
    on(trace, "subtask_index", 19, value=3)
    succeed_at(trace, 19)
    segments = cut_segments(trace, CHAIN, truncated=False)
    assert [(s.start, s.end, s.outcome.outcome) for s in segments] == [(0, 6, "S"), (6, 12, "S"), (12, 20, "S")]
    assert segments[1].outcome.events.t_reach == 3 and segments[2].outcome.events.t_o == 2
    assert [s.outcome.mode for s in segments] == ["Successful grasp handoff", "Successful navigation",
                                                  "Successful placement"]


def test_stage_active_at_the_time_limit_is_truncated():
    trace = chain_trace()
    on(trace, "subtask_index", 11, value=2)
    segments = cut_segments(trace, CHAIN, truncated=True)
    assert [s.outcome.outcome for s in segments] == ["S", "S", "T"]
    assert segments[2].outcome.mode == "No-alignment truncation"


def test_failure_on_a_stage_success_step_is_a_failure_and_ends_the_chain():
    trace = chain_trace()
    on(trace, "subtask_index", 11, value=2)
    fail_at(trace, 11, FailureCause.TILT)
    segments = cut_segments(trace, CHAIN, truncated=False)
    assert [(s.skill, s.outcome.outcome, s.outcome.cause) for s in segments] == [
        ("pick", "S", ""), ("nav", "F", "fail_tilt")]


def test_no_segments_for_an_init_failure():
    assert cut_segments(make_trace(CHAIN, 5, init_failed=True), CHAIN, truncated=True) == []
    assert cut_segments(chain_trace(), CHAIN, truncated=True, init_failed=True) == []


def test_pointer_must_fit_the_chain():
    trace = chain_trace()
    on(trace, "subtask_index", 8, value=5)
    with pytest.raises(ValueError, match="outside"):
        cut_segments(trace, CHAIN, truncated=True)
    with pytest.raises(ValueError, match="unknown skill"):
        cut_segments(chain_trace(), ("pick", "teleport"), truncated=True)


def test_segment_dict_is_json():
    trace = chain_trace()
    fail_at(trace, 11, FailureCause.COLLISION)
    data = [s.to_dict() for s in cut_segments(trace, CHAIN, truncated=False, parent_id="p")]
    assert json.loads(json.dumps(data)) == data
    assert data[1]["events"]["t_fail"] == 5 and data[1]["outcome"] == "F"


# ------------------------------------------------------------------------------------------------------------------
# Handoff eligibility of Place segments
# ------------------------------------------------------------------------------------------------------------------
def place_segment(**first_step):
    trace = make_trace("place", 10)
    for key, value in first_step.items():
        trace[key][0] = value
    (segment,) = cut_segments(trace, ("place",), truncated=True)
    return segment, trace


def test_held_start_outside_the_destination_is_eligible():
    segment, trace = place_segment()
    assert is_eligible_handoff(segment, trace) == (True, "held outside the destination support region")
    assert segment.eligible


@pytest.mark.parametrize(
    "first_step, reason",
    [
        ({"is_grasped": False}, "not held"),
        ({"is_support_contact": True}, "support contact"),
        ({"goal_distance": HANDOFF_GOAL_DISTANCE_M / 2}, "from the goal"),
        ({"goal_distance": HANDOFF_GOAL_DISTANCE_M}, "from the goal"),
    ],
)
def test_ineligible_place_starts(first_step, reason):
    segment, trace = place_segment(**first_step)
    eligible, why = is_eligible_handoff(segment, trace)
    assert not eligible and reason in why
    assert not segment.eligible and segment.eligibility == why


def test_eligibility_is_read_at_the_segment_start_in_the_parent():
    trace = chain_trace()
    on(trace, "subtask_index", 11, value=2)
    on(trace, "goal_distance", 0, 12, 0.0)  # close to the goal before Place starts: irrelevant
    segments = cut_segments(trace, CHAIN, truncated=True)
    assert segments[2].eligible
    on(trace, "goal_distance", 12, 13, 0.0)
    assert not cut_segments(trace, CHAIN, truncated=True)[2].eligible


def test_other_skills_carry_no_handoff_condition():
    segment = cut_segments(chain_trace(), CHAIN, truncated=True)[0]
    assert is_eligible_handoff(segment, chain_trace()) == (True, "no handoff condition for pick")
