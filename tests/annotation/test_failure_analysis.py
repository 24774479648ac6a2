"""The spec's failure-analysis diagnostics per episode (`annotation.failure_analysis`) and their per-cell summary."""

import math

import numpy as np
import pytest

from aerobench.annotation.failure_analysis import PINCHED_BEYOND, SLIP, failure_analysis
from aerobench.eval.results import failure_summary


def _pick(T: int = 10, **overrides) -> dict[str, np.ndarray]:
    signals = {k: np.zeros(T) for k in ("grasp_force_left", "grasp_force_right", "speed", "is_grasped",
                                          "object_displacement", "object_rotation", "nontarget_contact_force",
                                          "success")}
    for key, (t, value) in overrides.items():
        signals[key][t:] = value
    return signals


def test_pick_mechanisms_speed_at_contact_knocked_hit_and_handoff_rotation():
    s = _pick(grasp_force_left=(3, 0.5), is_grasped=(5, 1), success=(8, 1), object_rotation=(8, math.radians(12.0)))
    s["speed"][:] = np.linspace(0.5, 0.0, 10)
    d = failure_analysis("pick", s)
    assert d["speed_at_finger_contact_mps"] == pytest.approx(s["speed"][3])
    assert d["knocked_object"] is False and d["hit_scene"] is False
    assert d["handoff_rotation_deg"] == pytest.approx(12.0)
    knocked = _pick(object_displacement=(2, 0.05), is_grasped=(5, 1))  # pushed 5 cm before the grasp
    assert failure_analysis("pick", knocked)["knocked_object"] is True
    turned = _pick(object_rotation=(2, math.radians(25.0)))  # never grasped: the whole episode counts
    assert failure_analysis("pick", turned)["knocked_object"] is True
    after = _pick(is_grasped=(2, 1), object_displacement=(4, 0.2))  # lifted after the grasp: not knocked
    assert failure_analysis("pick", after)["knocked_object"] is False
    hit = _pick(nontarget_contact_force=(1, 50.0))
    assert failure_analysis("pick", hit)["hit_scene"] is True
    hit_after_knock = _pick(object_displacement=(1, 0.05))
    hit_after_knock["nontarget_contact_force"][3] = 50.0  # the object was already disturbed: not "hit the scene"
    assert failure_analysis("pick", hit_after_knock)["hit_scene"] is False
    assert failure_analysis("pick", _pick())["speed_at_finger_contact_mps"] is None  # never touched


def _transport(held: list[int], distance: list[float]) -> dict[str, np.ndarray]:
    return {"is_grasp_held": np.array(held, dtype=bool), "tcp_to_grasp_point": np.array(distance)}


def test_grasp_loss_mechanism_slip_or_pinched_beyond_six_centimetres():
    slip = failure_analysis("nav", _transport([1, 1, 1, 0, 0, 0, 0, 0], [0.01] * 8))
    assert slip == {"grasp_loss_step": 3, "grasp_loss_mechanism": SLIP}
    pinched = failure_analysis("nav", _transport([1] * 8, [0.01, 0.01, 0.07, 0.08, 0.09, 0.09, 0.1, 0.1]))
    assert pinched == {"grasp_loss_step": 2, "grasp_loss_mechanism": PINCHED_BEYOND}
    brief = failure_analysis("nav", _transport([1, 0, 0, 0, 1, 1], [0.01] * 6))  # 3 violations: not a loss
    assert brief["grasp_loss_mechanism"] is None


def test_release_speed_is_the_speed_when_the_jaws_open():
    signals = {"is_released": np.array([0, 0, 0, 1, 1]), "speed": np.array([0.3, 0.2, 0.1, 0.004, 0.0])}
    assert failure_analysis("place", signals)["speed_at_release_mps"] == pytest.approx(0.004)


def test_the_cell_summary_counts_mechanisms_and_losses_by_handoff_rotation():
    def chain(outcome, rotation, loss):
        return {"skill": "pick_nav_place", "outcome": outcome, "segments": [
            {"skill": "pick", "outcome": "S", "diagnostics": {"handoff_rotation_deg": rotation,
                                                                "speed_at_finger_contact_mps": 0.01}},
            {"skill": "nav", "outcome": "F" if loss else "S", "diagnostics": {"grasp_loss_mechanism": loss}}]}

    rows = [chain("S", 1.0, None), chain("F", 20.0, SLIP), chain("F", 30.0, PINCHED_BEYOND), chain("S", 5.0, None)]
    fa = failure_summary(rows)
    assert fa["transport"]["grasp_losses"] == {SLIP: 1, PINCHED_BEYOND: 1}
    assert fa["transport"]["losses_by_handoff_rotation_deg"] == {"<2": [0, 1], ">16": [2, 2], "2-16": [0, 1]}
    assert fa["pick"]["median_handoff_rotation_deg"] == pytest.approx(12.5) and fa["pick"]["failures"] == 0
    picks = [{"skill": "pick", "outcome": o, "diagnostics": {"knocked_object": k, "hit_scene": h,
                                                             "speed_at_finger_contact_mps": None}}
             for o, k, h in (("F", True, False), ("T", False, True), ("S", False, True))]
    pick = failure_summary(picks)["pick"]
    assert (pick["failures"], pick["failures_knocked_object"], pick["failures_hit_scene"]) == (2, 1, 1)
    old = [{"skill": "pick", "outcome": "F", "diagnostics": {"max_speed_mps": 1.0}}]  # written before the diagnostics
    assert failure_summary(old) == {}
