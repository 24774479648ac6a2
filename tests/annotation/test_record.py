"""The episode record: exact JSON round trips (null for never-observed events), version, derived duration."""

from __future__ import annotations

import json

import numpy as np
import pytest

from aerobench.annotation import RECORD_VERSION, EpisodeRecord, categorize, cut_segments
from aerobench.envs.checks import FailureCause
from aerobench.envs.platforms import CONTROL_HZ

from .test_events import fail_at, make_trace, on
from .test_segments import CHAIN, chain_trace

IDS = dict(episode_index=3, parent_id="TidyHouse/expert/shard-1/3", seed=1234, shard=1, setting="TidyHouse",
           object="tomato_soup_can", platform="gripper", policy="expert")


def pick_record() -> EpisodeRecord:
    trace = make_trace("pick", 30, min_obstacle_clearance=np.inf)  # no obstacle: an infinite clearance
    on(trace, "is_grasped", 4)
    return EpisodeRecord.from_outcome(categorize("pick", trace, truncated=True), **IDS)


def test_round_trip_is_exact():
    record = pick_record()
    text = record.to_json()
    assert EpisodeRecord.from_json(text) == record
    assert EpisodeRecord.from_json(text).to_json() == text
    assert "\n" not in text  # one JSONL line


def test_fields_and_nulls():
    record = pick_record()
    data = json.loads(record.to_json())
    assert data["version"] == RECORD_VERSION == 1
    assert (data["outcome"], data["mode"], data["cause"]) == ("T", "Grasp-without-lift truncation", "")
    assert data["events"]["t_g"] == 4 and data["events"]["t_l"] is None  # infinity is null
    assert data["diagnostics"]["min_obstacle_clearance_m"] is None
    assert data["steps"] == 30 and data["duration_s"] == 30 / CONTROL_HZ == 1.5
    assert data["skill"] == "pick" and data["segments"] == []
    for key, value in IDS.items():
        assert data[key] == value


def test_chain_record_with_segments_round_trips():
    trace = chain_trace()
    fail_at(trace, 11, FailureCause.COLLISION)
    segments = cut_segments(trace, CHAIN, truncated=False, parent_id=IDS["parent_id"])
    # the parent's own outcome: the chain failed in its Nav stage
    parent = categorize("nav", trace, truncated=False)
    record = EpisodeRecord.from_outcome(parent, skill="PackageDelivery", segments=segments, **IDS)
    again = EpisodeRecord.from_json(record.to_json())
    assert again == record
    assert [s["outcome"] for s in again.segments] == ["S", "F"]
    assert again.segments[0]["events"]["t_g"] == 2 and again.skill == "PackageDelivery"


def test_numpy_values_are_stored_as_plain_json():
    record = EpisodeRecord(skill="pick", outcome="S", mode="m", cause="", events={"t_g": np.int64(2)}, steps=np.int64(4),
                           diagnostics={"x": np.float32(0.5), "ok": np.bool_(True)}, **IDS)
    again = EpisodeRecord.from_json(record.to_json())
    assert again == record and again.events == {"t_g": 2} and again.diagnostics == {"x": 0.5, "ok": True}


def test_non_finite_values_are_rejected():
    with pytest.raises(ValueError):
        EpisodeRecord(skill="pick", outcome="S", mode="m", cause="", events={}, steps=1, diagnostics={"x": float("nan")}, **IDS)


def test_invalid_records_are_rejected():
    with pytest.raises(ValueError, match="outcome"):
        EpisodeRecord(skill="pick", outcome="X", mode="m", cause="", events={}, steps=1, **IDS)
    data = json.loads(pick_record().to_json())
    with pytest.raises(ValueError, match="version"):
        EpisodeRecord.from_dict({**data, "version": 2})
    with pytest.raises(ValueError, match="unknown"):
        EpisodeRecord.from_dict({**data, "extra": 1})
    with pytest.raises(ValueError, match="duration_s"):
        EpisodeRecord.from_dict({**data, "duration_s": 99.0})


def test_init_failure_record():
    outcome = categorize("place", make_trace("place", 1, init_failed=True), truncated=False)
    record = EpisodeRecord.from_outcome(outcome, **IDS)
    assert (record.outcome, record.steps, record.duration_s) == ("I", 0, 0.0)
    assert EpisodeRecord.from_json(record.to_json()) == record
