"""Event extraction against hand-built signal traces (spec: t_b = min{t : b_t = 1}, infinity when never observed).

`make_trace`, `on`, `fail_at` and `succeed_at` build the traces every annotation test uses.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from aerobench.annotation import Events, extract_events, first_streak, first_time, required_keys, summarize
from aerobench.annotation.events import (
    CLEARANCE_M,
    NONTARGET_CONTACT_N,
    PAYLOAD_LOSS_STEPS,
    PLATFORM_STABLE_MPS,
    PLATFORM_STABLE_STEPS,
    payload_loss_time,
)
from aerobench.envs.checker import COMMON_INFO_KEYS, SKILL_INFO_KEYS
from aerobench.envs.checks import FailureCause

# A quiet trace: flying, nothing happening, nothing latched.
COMMON = {
    "success": False, "fail": False, "fail_cause": 0, "is_success": False, "tilt": 0.05, "altitude": 1.2,
    "speed": 0.3, "angular_speed": 0.1, "nontarget_contact_force": 0.0, "airframe_contact_force": 0.0,
    "gripper_opening": 0.05, "min_obstacle_clearance": 0.5, "init_failed": False, "subtask_index": 0,
    "fail_tilt": False, "fail_low": False, "fail_high": False, "fail_workspace": False,
}
PER_SKILL = {
    "pick": {"is_grasped": False, "is_grasp_held": False, "lift_height": 0.0, "is_lifted": False,
             "object_height": 0.8, "tcp_to_grasp_point": 0.6, "is_object_supported": True, "grasp_force_left": 0.0,
             "grasp_force_right": 0.0, "object_displacement": 0.0, "object_rotation": 0.0},
    "place": {"is_grasped": True, "goal_distance": 0.5, "is_aligned": False, "is_support_contact": False,
              "is_released": False, "release_registered": False, "is_gripper_clear": False,
              "platform_stable_steps": 0, "collision_impulse": 0.0, "is_set_down": False,
              "is_object_supported": False},
    "nav": {"nav_distance": 0.8, "is_nav_reached": False, "nav_settle_steps": 0},
    "open": {"articulation_progress": 0.0, "is_handle_pinched": False, "is_goal_reached": False,
             "is_released_handle": False, "is_arm_retracted": False, "is_platform_stable": False,
             "no_airframe_contact": True, "min_clearance": 0.2, "phase": 0},
}
PER_SKILL["close"] = PER_SKILL["open"]
ENVELOPE_FLAG = {FailureCause.TILT: "fail_tilt", FailureCause.LOW: "fail_low", FailureCause.HIGH: "fail_high",
                 FailureCause.WORKSPACE: "fail_workspace"}


def make_trace(skills: str | tuple[str, ...], steps: int, **constants) -> dict[str, np.ndarray]:
    """A quiet `(steps,)` trace with every signal the skills' envs report; `constants` override whole signals."""
    values = dict(COMMON)
    for skill in (skills,) if isinstance(skills, str) else skills:
        values.update(PER_SKILL[skill])
    values.update(constants)
    return {key: np.full(steps, value) for key, value in values.items()}


def on(trace: dict, key: str, start: int, stop: int | None = None, value=True) -> dict:
    """`trace[key][start:stop] = value`."""
    trace[key][start:stop] = value
    return trace


def fail_at(trace: dict, t: int, cause: FailureCause) -> dict:
    """Latch `cause` from step t (and raise its envelope flag on step t, as the env would)."""
    on(trace, "fail_cause", t, value=int(cause))
    on(trace, "fail", t)
    if cause in ENVELOPE_FLAG:
        on(trace, ENVELOPE_FLAG[cause], t, t + 1)
    return trace


def succeed_at(trace: dict, t: int) -> dict:
    on(trace, "success", t)
    return on(trace, "is_success", t)


def test_builder_covers_the_env_signals():
    for skill, keys in SKILL_INFO_KEYS.items():
        trace = make_trace(skill, 3)
        assert set(COMMON_INFO_KEYS) | set(keys) <= set(trace), skill
        assert set(required_keys(skill)) <= set(trace), skill


@pytest.mark.parametrize(
    "flags, expected",
    [([], None), ([0, 0, 0], None), ([1, 0, 1], 0), ([0, 0, 1, 1], 2), ([False, True], 1), (np.array([0.0, 2.0]), 1)],
)
def test_first_time(flags, expected):
    assert first_time(np.asarray(flags)) == expected


@pytest.mark.parametrize(
    "flags, length, expected",
    [([1, 1, 0, 1, 1, 1], 3, 3), ([1, 1, 0, 1, 1], 3, None), ([1], 1, 0), ([], 2, None), ([0, 1, 1], 2, 1)],
)
def test_first_streak(flags, length, expected):
    assert first_streak(np.asarray(flags), length) == expected


def test_first_streak_rejects_empty_length():
    with pytest.raises(ValueError, match="length"):
        first_streak(np.ones(3), 0)


def test_quiet_trace_has_no_events():
    for skill in ("pick", "place", "nav", "open", "close"):
        events = extract_events(skill, make_trace(skill, 25))
        observed = {k: v for k, v in events.as_dict().items() if v is not None and not k.endswith("progress")}
        assert observed == {}, skill


def test_pick_events():
    trace = make_trace("pick", 12)
    on(trace, "is_grasped", 3, 6)
    on(trace, "is_lifted", 5)
    events = extract_events("pick", trace)
    assert (events.t_g, events.t_l) == (3, 5)
    assert events.t_o is None and events.t_reach is None  # another skill's events stay unset


def test_place_events_are_independent_observations():
    # release observed before alignment: reported as seen, no stage order imposed
    trace = make_trace("place", 15)
    on(trace, "is_released", 2, 3)
    on(trace, "is_aligned", 6)
    on(trace, "is_support_contact", 8)
    on(trace, "is_gripper_clear", 11)
    events = extract_events("place", trace)
    assert (events.t_o, events.t_d, events.t_r, events.t_c) == (6, 8, 2, 11)


def test_nav_and_articulation_events():
    nav = on(make_trace("nav", 10), "is_nav_reached", 7)
    assert extract_events("nav", nav).t_reach == 7
    trace = make_trace("open", 10)
    trace["articulation_progress"] = np.linspace(0.0, 0.8, 10)
    on(trace, "is_handle_pinched", 2)
    on(trace, "is_goal_reached", 9)
    events = extract_events("open", trace)
    assert (events.t_pinch, events.t_goal) == (2, 9)
    assert events.max_progress == pytest.approx(0.8) and events.min_progress == 0.0


def test_aerial_constraint_events():
    trace = make_trace("pick", 40)
    for key, t in (("fail_tilt", 4), ("fail_low", 5), ("fail_high", 6), ("fail_workspace", 7)):
        on(trace, key, t, t + 1)
    on(trace, "nontarget_contact_force", 8, 9, NONTARGET_CONTACT_N)  # at the threshold: not yet a contact
    on(trace, "nontarget_contact_force", 10, 11, 2 * NONTARGET_CONTACT_N)
    on(trace, "airframe_contact_force", 12, 13, 5.0)
    on(trace, "min_obstacle_clearance", 14, 15, CLEARANCE_M / 2)
    on(trace, "speed", 15, 15 + PLATFORM_STABLE_STEPS, PLATFORM_STABLE_MPS / 2)
    events = extract_events("pick", trace)
    assert (events.t_tilt, events.t_low, events.t_high, events.t_workspace) == (4, 5, 6, 7)
    assert (events.t_contact, events.t_airframe_contact, events.t_clearance, events.t_stable) == (10, 12, 14, 15)


def test_platform_stability_needs_a_full_streak():
    trace = on(make_trace("place", 40), "speed", 5, 5 + PLATFORM_STABLE_STEPS - 1, 0.0)
    assert extract_events("place", trace).t_stable is None


def test_articulation_uses_its_own_stability_and_clearance_signals():
    trace = make_trace("close", 30, speed=0.0)  # slow but not is_platform_stable: the spec's V check decides
    on(trace, "is_platform_stable", 3)
    on(trace, "min_clearance", 9, 10, 0.0)
    on(trace, "airframe_contact_force", 4, 5, 0.5)  # below the collision limit but the N check saw it
    on(trace, "no_airframe_contact", 4, value=False)
    events = extract_events("close", trace)
    assert (events.t_stable, events.t_clearance, events.t_airframe_contact) == (3, 9, 4)


def test_payload_loss():
    trace = make_trace("nav", 15, is_grasped=True, is_object_supported=False)
    on(trace, "is_grasped", 6, value=False)
    assert payload_loss_time(trace) == 6
    assert extract_events("nav", trace).t_payload_loss == 6


def test_payload_loss_needs_a_held_grasp_and_a_lasting_loss():
    never_held = make_trace("pick", 15, is_object_supported=False)
    assert payload_loss_time(never_held) is None
    flicker = make_trace("nav", 15, is_grasped=True, is_object_supported=False)
    on(flicker, "is_grasped", 4, 4 + PAYLOAD_LOSS_STEPS - 1, False)
    assert payload_loss_time(flicker) is None
    no_object = {k: v for k, v in make_trace("nav", 5).items()}
    assert payload_loss_time(no_object) is None


def test_setting_down_or_releasing_is_not_payload_loss():
    set_down = make_trace("place", 15)
    on(set_down, "is_support_contact", 5)
    on(set_down, "is_grasped", 6, value=False)
    assert extract_events("place", set_down).t_payload_loss is None
    released = make_trace("place", 15, is_support_contact=False)
    on(released, "is_released", 5, 6)
    on(released, "is_grasped", 6, value=False)
    assert extract_events("place", released).t_payload_loss is None
    pick_from_table = on(make_trace("pick", 15), "is_grasped", 2, 4)  # the object still stands on its support
    assert extract_events("pick", pick_from_table).t_payload_loss is None


def test_outcome_flag_times():
    trace = fail_at(succeed_at(make_trace("pick", 10), 6), 3, FailureCause.COLLISION)
    events = extract_events("pick", trace)
    assert (events.t_success, events.t_fail) == (6, 3)


def test_missing_signal_is_named():
    trace = make_trace("pick", 5)
    del trace["is_lifted"]
    with pytest.raises(KeyError, match="is_lifted"):
        extract_events("pick", trace)


def test_unknown_skill():
    with pytest.raises(ValueError, match="unknown skill 'fly'"):
        extract_events("fly", make_trace("pick", 5))


def test_torch_signals_are_accepted():
    trace = {k: torch.as_tensor(v) for k, v in on(make_trace("pick", 8), "is_grasped", 4).items()}
    assert extract_events("pick", trace).t_g == 4


def test_signals_must_be_one_env():
    trace = make_trace("pick", 5)
    trace["is_grasped"] = np.zeros((5, 2), dtype=bool)
    with pytest.raises(ValueError, match="one env"):
        extract_events("pick", trace)


def test_events_dict_round_trip():
    events = Events(t_g=1, t_l=None, max_progress=0.5)
    assert Events.from_dict(events.as_dict()) == events
    assert set(events.as_dict()) == {f.name for f in dataclasses.fields(Events)}
    with pytest.raises(ValueError, match="unknown event"):
        Events.from_dict({"t_x": 1})


def test_summarize_keeps_diagnostics_of_the_skill():
    trace = make_trace("pick", 10)
    trace["tilt"] = np.linspace(0.0, 0.3, 10)
    on(trace, "nontarget_contact_force", 4, 5, 0.7)
    on(trace, "min_obstacle_clearance", 6, 7, 0.04)
    on(trace, "fail_tilt", 8)
    trace["goal_distance"] = np.zeros(10)  # another stage's signal (reads 0 in a chain): not a Pick diagnostic
    out = summarize("pick", trace)
    assert out["max_tilt_rad"] == pytest.approx(0.3)
    assert out["max_nontarget_contact_force_n"] == pytest.approx(0.7)
    assert out["min_obstacle_clearance_m"] == pytest.approx(0.04)
    assert out["fail_tilt_steps"] == 2
    assert "min_goal_distance_m" not in out
    assert all(type(v) in (int, float, bool) for v in out.values())


def test_summarize_turns_non_finite_into_none():
    trace = make_trace("open", 4, min_clearance=np.inf)
    assert summarize("open", trace)["min_clearance_m"] is None
