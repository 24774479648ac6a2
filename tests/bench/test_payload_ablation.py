"""`bench/payload_ablation.py`: its analysis on synthetic episodes whose answers are known by construction (outcome
rows, lift-off, carry metrics, the spec's single-carry rule, the tilt-rate PSD), its resumable episode file, and one
real chained expert episode through the product's runner carrying the kept signals."""

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

import payload_ablation as pa  # noqa: E402

from aerobench.envs.checks import FailureCause  # noqa: E402
from aerobench.envs.platforms import CONTROL_HZ  # noqa: E402


def _episode(index, obj, *, steps=400, grasp=50, lift_after=20, handoff=100, place=300, outcome="S", cause=0,
             tilt_hz=None, init_failed=False):
    t = np.arange(steps)
    height = np.where(t >= grasp + lift_after, 0.10, 0.0)
    stage = np.where(t >= place, 2, np.where(t >= handoff, 1, 0))
    tilt_rate = np.radians(5.0) * (np.sin(2 * np.pi * tilt_hz * t / CONTROL_HZ) if tilt_hz else np.ones(steps))
    signals = dict(subtask_index=stage, fail_cause=np.full(steps, cause), is_grasped=(t >= grasp).astype(float),
                   object_height=height, tcp_height=height + 0.05, integral_z=np.where(stage == 1, -0.5, 0.0),
                   tilt=np.zeros(steps), tilt_rate=tilt_rate)
    return dict(index=index, seed=1000 + index, object=obj, init_failed=init_failed, record=dict(outcome=outcome), signals={k: v.tolist() for k, v in signals.items()})


def test_outcome_rows_follow_the_cause_and_the_stage():
    assert pa.outcome_row(_episode(0, "bowl")) == "success"
    assert pa.outcome_row(_episode(0, "bowl", init_failed=True, outcome="I")) == "initialization rejection"
    drop = int(FailureCause.OBJECT_DROP)
    assert pa.outcome_row(_episode(0, "bowl", outcome="F", cause=drop)) == "grasp lost"
    hit = int(FailureCause.COLLISION)
    assert pa.outcome_row(_episode(0, "bowl", outcome="F", cause=hit, handoff=1000, place=1000)) == "collision (pick)"
    assert pa.outcome_row(_episode(0, "bowl", outcome="F", cause=hit, place=1000)) == "collision (transport)"
    assert pa.outcome_row(_episode(0, "bowl", outcome="T")) == "timeout"


def test_lift_off_and_carry_metrics_match_the_construction():
    m = pa.episode_metrics(_episode(0, "bowl", grasp=50, lift_after=30, handoff=100, place=300))
    assert m["grasp_step"] == 50 and m["lift_off_s"] == pytest.approx(30 / CONTROL_HZ)
    assert m["carry_steps"] == 200 and m["mean_abs_xi_z"] == pytest.approx(0.5)
    assert m["rms_tilt_rate"] == pytest.approx(5.0)
    never = pa.episode_metrics(_episode(1, "bowl", lift_after=10_000))
    assert never["never_lifted"] and never["lift_off_s"] is None
    # the median over grasped episodes counts a never-lifted one as infinitely late
    assert pa.median_lift_off([never, never, m]) == (None, True)
    assert pa.median_lift_off([never, m, m]) == (pytest.approx(1.5), False)


def test_single_carry_rule_and_psd_peak():
    heavy = pa.HEAVY_CANS[0]
    assert set(pa.HEAVY_CANS) == {"master_chef_can", "tomato_soup_can", "potted_meat_can"}
    drop = int(FailureCause.OBJECT_DROP)
    aware = [_episode(i, heavy, steps=400 + 10 * i, place=380, tilt_hz=3.0) for i in range(3)]
    nominal = [_episode(i, heavy, steps=500 + 100 * i, outcome="F", cause=drop, place=10_000, tilt_hz=1.4)
               for i in range(3)]
    results = {"payload-aware": aware, "nominal": nominal}
    summary = pa.analyse(results)
    carry = summary["single_carry"]
    assert carry["rule"].startswith("succeeds payload-aware and loses the grasp") and carry["candidates"] == 3
    assert carry["index"] == 1  # the median nominal episode length of the three
    assert carry["series"]["nominal"]["grasp_lost_s"] is not None
    peak = summary["psd"]["nominal_peak"]
    assert abs(peak["freq_hz"] - 1.4) < 0.2 and peak["payload_aware"] < peak["nominal"]
    assert summary["outcomes"]["nominal"]["grasp lost"] == 3 and summary["overall"]["payload-aware"]["success"] == 3
    json.dumps(summary, allow_nan=False)  # the committed JSON is strict JSON


def test_episode_file_resumes_past_a_cut_line(tmp_path):
    path = tmp_path / "shard.jsonl"
    path.write_text(json.dumps(dict(index=0)) + "\n" + json.dumps(dict(index=1)) + "\n" + '{"index": 2, "sig')
    assert pa.JsonLinesSink(path).done_indices() == {0, 1}


def test_one_real_chained_episode_keeps_the_carry_signals(tmp_path):
    """The product's runner under the chained protocol, payload-aware: the kept signals have one value per step and
    the episode line carries its record."""
    out = pa.run_shard("payload-aware", 0, 1, 1, 30, str(tmp_path))
    (line,) = pa.read_lines(Path(out))
    steps = {len(v) for v in line["signals"].values()}
    assert set(line["signals"]) == set(pa.SIGNALS) and len(steps) == 1 and steps.pop() >= line["record"]["steps"]
    m = pa.episode_metrics(line)
    assert m["outcome"] in pa.OUTCOME_ROWS
    assert max(abs(v) for v in line["signals"]["integral_z"]) <= 2.0 + 1e-6  # the gripper platform's integrator limit
    assert not math.isnan(sum(line["signals"]["tilt_rate"]))
    # a second call resumes: nothing is run again, nothing duplicated
    pa.run_shard("payload-aware", 0, 1, 1, 30, str(tmp_path))
    assert len(pa.read_lines(Path(out))) == 1
