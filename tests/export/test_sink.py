"""DatasetSink: real LeRobot datasets from tiny synthetic episodes, reloaded with `LeRobotDataset`; keep filter,
crash safety and resume, a different spec, shards."""

import json
import os

import numpy as np
import pytest

from aerobench.annotation.record import EpisodeRecord
from aerobench.depth import decode_depth_mm
from aerobench.envs.observations import TASK_STATE_VERSION
from aerobench.envs.tasks import SKILLS
from aerobench.export import sink as sink_module
from aerobench.export.features import depth_key, rgb_key
from aerobench.export.layout import (
    EPISODES_FILE,
    completed_parts,
    dataset_task_state_version,
    read_jsonl,
    record_from_row,
)
from aerobench.export.sink import DatasetSink, merge_parts
from aerobench.rollout.episode import CAMERAS, EVENT_FLAGS, EpisodeData

os.environ.setdefault("HF_HUB_OFFLINE", "1")
SPEC = {"setting": "TidyHouse", "skills": ["nav", "pick"], "seed": 7, "episodes": 6, "objects": ["apple"], "policy": "expert"}
STEPS = (3, 4, 5, 3, 4, 6)
EPISODE_SKILLS = ("nav", "pick")  # episode-local indices 0, 1 -> dataset indices SKILLS.index(...)


def make_record(index: int, *, steps: int, outcome="S", mode="success", obj="apple", platform="gripper", shard=0):
    return EpisodeRecord(
        episode_index=index, parent_id=f"TidyHouse/expert/{index}", seed=100 + index, shard=shard,
        setting="TidyHouse", skill="pick", object=obj, platform=platform, policy="expert", outcome=outcome,
        mode=mode, cause="" if outcome == "S" else "drop", events={"t_g": 1}, steps=steps,
    )


def make_episode(index: int, *, cameras=False, steps=None, **record_kw) -> EpisodeData:
    """An episode whose state[:, 0] = index + t / 100 identifies it in any dataset it lands in."""
    steps = STEPS[index % len(STEPS)] if steps is None else steps
    rng = np.random.default_rng(index)
    state = rng.standard_normal((steps, 19)).astype(np.float32)
    state[:, 0] = index + np.arange(steps) / 100
    frames = {
        "state": state,
        "action": rng.uniform(-1, 1, (steps, 5)).astype(np.float32),
        "skill": (np.arange(steps) >= steps // 2).astype(np.int64),
        "stage": (np.arange(steps) >= steps // 2).astype(np.int64),
        "phase": np.arange(steps, dtype=np.int64) % 3,
        "events": (rng.random((steps, len(EVENT_FLAGS))) > 0.5).astype(np.float32),
    }
    if cameras:
        for camera in CAMERAS:
            frames[f"rgb/{camera}"] = rng.integers(0, 256, (steps, 128, 128, 3), dtype=np.uint8)
            frames[f"depth/{camera}"] = rng.integers(0, 10_001, (steps, 128, 128), dtype=np.uint16)
    record = make_record(index, steps=steps, **record_kw)
    return EpisodeData(record, frames, task=f"pick up the {record.object} #{index % 2}", skills=EPISODE_SKILLS,
                       extra={"object_mass_kg": np.float32(0.25), "env_id": "AeroPick-v1"})


def load(root):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    return LeRobotDataset("local/x", root=root)


def state_column(dataset) -> tuple[np.ndarray, np.ndarray]:
    table = dataset.hf_dataset.select_columns(["episode_index", "observation.state"]).with_format("numpy")
    return np.asarray(table["episode_index"]), np.stack(table["observation.state"])


def assert_aligned(root, expected_indices=None) -> list[dict]:
    """aerobench_episodes.jsonl row i describes dataset episode i (checked through the identifying state)."""
    dataset = load(root)
    rows = read_jsonl(root / "meta" / EPISODES_FILE)
    assert [r["dataset_episode_index"] for r in rows] == list(range(dataset.num_episodes))
    episode_of_frame, state = state_column(dataset)
    for i, row in enumerate(rows):
        ep_state = state[episode_of_frame == i]
        assert len(ep_state) == row["steps"]
        assert np.allclose(ep_state[:, 0], row["episode_index"] + np.arange(row["steps"]) / 100)
    if expected_indices is not None:
        assert sorted(r["episode_index"] for r in rows) == sorted(expected_indices)
    return rows


def write_all(sink, indices, **kw):
    for i in indices:
        sink.write(make_episode(i, **kw))


@pytest.fixture(scope="module")
def camera_root(tmp_path_factory):
    """Three camera episodes in two parts (part_size 2), merged: the full feature set through aggregation."""
    root = tmp_path_factory.mktemp("cameras") / "ds"
    sink = DatasetSink(root, SPEC, keep=None, part_size=2)
    episodes = [make_episode(i, cameras=True, steps=3) for i in range(3)]
    for episode in episodes:
        sink.write(episode)
    sink.close()
    return root, episodes


def test_camera_dataset_loads_with_every_feature(camera_root):
    root, episodes = camera_root
    dataset = load(root)
    assert dataset.num_episodes == 3 and dataset.num_frames == 9 and dataset.fps == 20
    assert dataset.meta.robot_type == "aerobench_gripper"
    for camera in CAMERAS:
        assert dataset.features[rgb_key(camera)]["dtype"] == "video"
        assert dataset.features[depth_key(camera)]["dtype"] == "image"
    assert dataset.features["observation.state"]["names"][0] == "position.0"
    assert dataset.features["action"]["names"] == ["u_x", "u_y", "u_z", "u_psi", "u_g"]
    assert dataset.features["annotation.events"]["names"] == list(EVENT_FLAGS)
    rows = assert_aligned(root, range(3))
    frame = 0
    for i, (row, episode) in enumerate(zip(rows, episodes, strict=True)):
        assert row["task"] == episode.task and row["extra"] == {"object_mass_kg": 0.25, "env_id": "AeroPick-v1"}
        for t in range(episode.num_frames):
            item = dataset[frame]
            assert item["task"] == episode.task and int(item["episode_index"]) == i
            expected_skill = SKILLS.index(EPISODE_SKILLS[episode.frames["skill"][t]])
            assert int(item["annotation.skill"]) == expected_skill
            assert int(item["annotation.stage"]) == episode.frames["stage"][t]
            assert int(item["annotation.phase"]) == episode.frames["phase"][t]
            assert np.array_equal(item["annotation.events"].numpy(), episode.frames["events"][t])
            assert np.array_equal(item["action"].numpy(), episode.frames["action"][t])
            assert item[rgb_key("drone_front")].shape == (3, 128, 128)
            for camera in CAMERAS:  # lossless through the part's parquet and the merge
                assert np.array_equal(decode_depth_mm(item[depth_key(camera)]), episode.frames[f"depth/{camera}"][t])
            frame += 1
    meta = json.loads((root / "meta" / "aerobench.json").read_text())
    assert meta["skills"] == list(SKILLS) and meta["generation"] == {**SPEC, "task_state_version": TASK_STATE_VERSION}
    assert dataset_task_state_version(root) == TASK_STATE_VERSION
    written = (root / "meta" / "aerobench.json").read_text()
    del meta["generation"]["task_state_version"]  # as written before versions were recorded
    (root / "meta" / "aerobench.json").write_text(json.dumps(meta))
    assert dataset_task_state_version(root) == 1
    (root / "meta" / "aerobench.json").write_text(written)
    assert len(completed_parts(root)) == 2 and not any(p.name.startswith(".tmp") for p in (root / ".aerobench/parts").iterdir())


def test_keep_filter_records_every_episode(tmp_path):
    root = tmp_path / "ds"
    sink = DatasetSink(root, SPEC, keep=lambda r: r.outcome == "S", part_size=2)
    for i, outcome in enumerate("SFFF"):
        sink.write(make_episode(i, outcome=outcome, mode="success" if outcome == "S" else "dropped"))
    sink.write(make_episode(4, steps=0, outcome="I", mode="init_failure"))  # zero frames: a record only
    sink.write(make_episode(5))
    sink.close()
    dataset = load(root)
    assert dataset.num_episodes == 2 and not dataset.meta.camera_keys  # a state-only dataset
    rows = assert_aligned(root, [0, 5])
    assert all(r["outcome"] == "S" for r in rows)
    records = read_jsonl(root / ".aerobench" / "records.jsonl")
    kept = [(r["episode_index"], r["in_dataset"]) for r in records]
    assert kept == [(0, True), (1, False), (2, False), (3, False), (4, False), (5, True)]
    assert record_from_row(records[1]) == make_record(1, steps=STEPS[1], outcome="F", mode="dropped")
    nothing_kept = root / ".aerobench" / "parts" / "part-000-000002-000003"
    assert [p.name for p in nothing_kept.iterdir()] == ["aerobench_records.jsonl"]
    assert DatasetSink(root, SPEC).done_indices() == set(range(6))


def test_no_kept_episode_writes_records_only(tmp_path):
    root = tmp_path / "ds"
    sink = DatasetSink(root, SPEC, keep=lambda r: False, part_size=2)
    for i in range(3):
        sink.write(make_episode(i))
    sink.close()
    assert sorted(p.name for p in root.iterdir()) == [".aerobench"]
    assert len(read_jsonl(root / ".aerobench" / "records.jsonl")) == 3


def test_crash_mid_run_then_resume_writes_each_episode_once(tmp_path):
    root = tmp_path / "ds"
    sink = DatasetSink(root, SPEC, keep=None, part_size=2)
    write_all(sink, range(5))  # parts [0, 1] and [2, 3] committed; episode 4 only buffered
    # "kill -9": no flush, no close; a half-written part of episode 4-5 stays behind
    half = root / ".aerobench" / "parts" / ".tmp-000-part-000-000004-000005-4242-deadbeef"
    (half / "data" / "chunk-000").mkdir(parents=True)
    (half / "data" / "chunk-000" / "file-000.parquet").write_bytes(b"PAR1 truncated")
    del sink

    restarted = DatasetSink(root, SPEC, keep=None, part_size=2)
    assert restarted.done_indices() == {0, 1, 2, 3}
    assert not half.exists()
    write_all(restarted, range(6))  # a runner that re-sends done episodes is harmless
    restarted.close()
    rows = assert_aligned(root, range(6))
    assert [r["episode_index"] for r in rows] == list(range(6))
    assert len(read_jsonl(root / ".aerobench" / "records.jsonl")) == 6


def test_killed_part_write_and_merge_leave_root_recoverable(tmp_path, monkeypatch):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = tmp_path / "ds"
    sink = DatasetSink(root, SPEC, keep=None, part_size=2)
    write_all(sink, range(2))
    sink.close()
    assert load(root).num_episodes == 2

    def killed(self):
        raise KeyboardInterrupt("killed while finalizing a part")

    monkeypatch.setattr(LeRobotDataset, "finalize", killed)
    crashing = DatasetSink(root, SPEC, keep=None, part_size=2)
    with pytest.raises(KeyboardInterrupt):
        write_all(crashing, range(2, 4))
    monkeypatch.undo()
    assert any(p.name.startswith(".tmp-") for p in (root / ".aerobench" / "parts").iterdir())
    assert_aligned(root, range(2))  # the merged dataset is untouched and still loads

    restarted = DatasetSink(root, SPEC, keep=None, part_size=2)
    assert restarted.done_indices() == {0, 1}
    write_all(restarted, range(2, 4))
    restarted.flush()

    def crash_mid_swap(root, work):
        import shutil

        shutil.rmtree(root / "meta")
        raise KeyboardInterrupt("killed while swapping the merged dataset in")

    monkeypatch.setattr(sink_module, "_swap_in", crash_mid_swap)
    with pytest.raises(KeyboardInterrupt):
        merge_parts(root)
    monkeypatch.undo()
    merge_parts(root)  # finishes the interrupted swap, then sees it is up to date
    assert_aligned(root, range(4))


def test_a_root_holding_something_else_is_refused_untouched(tmp_path):
    root = tmp_path / "ds"
    sink = DatasetSink(root, SPEC, keep=None, part_size=8)
    sink.write(make_episode(0))
    sink.flush()
    before = sorted((str(p), p.stat().st_mtime_ns) for p in root.rglob("*"))
    with pytest.raises(ValueError) as error:
        DatasetSink(root, {**SPEC, "seed": 8, "episodes": 9}, keep=None)
    message = str(error.value)
    assert "\n" not in message and "holds a different dataset (episodes, seed differ)" in message
    assert sorted((str(p), p.stat().st_mtime_ns) for p in root.rglob("*")) == before

    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="not an aerobench dataset"):
        DatasetSink(foreign, SPEC)
    assert [p.name for p in foreign.iterdir()] == ["notes.txt"]


def test_episodes_of_another_shape_are_refused(tmp_path):
    sink = DatasetSink(tmp_path / "ds", SPEC, part_size=8)
    sink.write(make_episode(0))
    with pytest.raises(ValueError, match="does not match this dataset"):
        sink.write(make_episode(1, cameras=True))
    with pytest.raises(ValueError, match="does not match this dataset"):
        sink.write(make_episode(2, platform="arm"))


def test_an_initialization_failure_without_frames_is_a_record_only_even_when_keeping_all(tmp_path):
    """The runner hands over an init failure with no frames at all; keep=None must not choke on it."""
    root = tmp_path / "ds"
    sink = DatasetSink(root, SPEC, keep=None, part_size=2)
    failed = make_episode(0, steps=0, outcome="I", mode="init_failure")
    failed.frames.clear()
    assert failed.num_frames == 0
    sink.write(failed)
    sink.write(make_episode(1))
    sink.close()
    assert load(root).num_episodes == 1
    records = read_jsonl(root / ".aerobench" / "records.jsonl")
    assert [(r["episode_index"], r["in_dataset"]) for r in records] == [(0, False), (1, True)]
