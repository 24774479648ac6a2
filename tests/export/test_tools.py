"""Dataset tools: shards merged by `merge`, `dataset_info` counts, `filter_dataset`, `clean_parts`."""

import json
import os

import numpy as np
import pytest

from aerobench.export import tools
from aerobench.export.info import dataset_info, format_info
from aerobench.export.layout import EPISODES_FILE, read_jsonl
from aerobench.export.sink import DatasetSink

from .test_sink import SPEC, assert_aligned, load, make_episode

os.environ.setdefault("HF_HUB_OFFLINE", "1")
# index: (outcome, mode, object)
EPISODES = {
    0: ("S", "success", "apple"),
    1: ("F", "dropped", "apple"),
    2: ("S", "success", "banana"),
    3: ("T", "timeout", "banana"),
    4: ("S", "success", "apple"),
    5: ("F", "collision", "banana"),
}


def episode(i: int, **kw):
    outcome, mode, obj = EPISODES[i]
    return make_episode(i, outcome=outcome, mode=mode, obj=obj, **kw)


@pytest.fixture(scope="module")
def sharded_root(tmp_path_factory):
    """Two shards writing parts into one root concurrently-style, merged afterwards by `tools.merge`."""
    root = tmp_path_factory.mktemp("shards") / "ds"
    shards = [DatasetSink(root, {**SPEC, "shard": [k, 2]}, keep=None, part_size=2) for k in range(2)]
    for i in EPISODES:
        shards[i % 2].write(episode(i, shard=i % 2))
    for shard in shards:
        shard.close()  # a shard never merges by itself
    assert not (root / "meta").exists()
    unmerged = dataset_info(root)
    assert (unmerged["merged"], unmerged["episodes"], unmerged["unmerged_parts"]) == (False, 6, 4)
    assert tools.merge(root) == root
    return root


def test_shards_merge_into_one_dataset(sharded_root):
    rows = assert_aligned(sharded_root, EPISODES)
    assert sorted({r["shard"] for r in rows}) == [0, 1]
    names = [p.name for p in (sharded_root / ".aerobench" / "parts").iterdir()]
    assert sorted(names) == ["part-000-000000-000002", "part-000-000004-000004", "part-001-000001-000003", "part-001-000005-000005"]
    assert tools.merge(sharded_root) == sharded_root  # up to date: nothing changes
    assert_aligned(sharded_root, EPISODES)


def test_dataset_info_counts(sharded_root):
    info = dataset_info(sharded_root)
    assert (info["merged"], info["episodes"], info["processed"], info["not_kept"], info["unmerged_parts"]) == (True, 6, 6, 0, 0)
    assert info["frames"] == sum(make_episode(i).num_frames for i in EPISODES)
    assert info["counts"]["outcome"] == {"S": 3, "F": 2, "T": 1}
    assert info["counts"]["mode"] == {"success": 3, "dropped": 1, "timeout": 1, "collision": 1}
    assert info["counts"]["object"] == {"apple": 3, "banana": 3}
    assert info["counts"]["setting"] == {"TidyHouse": 6} and info["counts"]["skill"] == {"pick": 6}
    assert info["features"]["observation.state"] == {"dtype": "float32", "shape": [19]}
    assert "observation.images.drone_front" not in info["features"]
    text = format_info(info)
    assert "episodes  6" in text and "S 3   F 2   T 1" in text and "observation.state" in text


def test_filter_by_outcome_and_object(sharded_root, tmp_path):
    dst = tools.filter_dataset(sharded_root, tmp_path / "ok_apple", outcomes=["S"], objects="apple")
    rows = assert_aligned(dst, [0, 4])
    assert all(r["outcome"] == "S" and r["object"] == "apple" for r in rows)
    meta = json.loads((dst / "meta" / "aerobench.json").read_text())
    assert meta["filter"] == {"outcome": ["S"], "object": ["apple"]} and "parts" not in meta
    assert dataset_info(dst)["counts"]["outcome"] == {"S": 2}

    failures = tools.filter_dataset(sharded_root, tmp_path / "failures", outcomes=["F", "T"])
    assert load(failures).num_episodes == 3
    assert_aligned(failures, [1, 3, 5])

    with pytest.raises(ValueError, match="no episode"):
        tools.filter_dataset(sharded_root, tmp_path / "none", objects=["cherry"])
    with pytest.raises(ValueError, match="not empty"):
        tools.filter_dataset(sharded_root, failures, outcomes=["S"])
    with pytest.raises(ValueError, match="unknown outcomes"):
        tools.filter_dataset(sharded_root, tmp_path / "bad", outcomes=["X"])


def test_filter_a_camera_dataset_keeps_depth_exact(tmp_path):
    from aerobench.depth import decode_depth_mm

    root = tmp_path / "ds"
    sink = DatasetSink(root, SPEC, keep=None, part_size=8)
    episodes = [episode(i, cameras=True, steps=2) for i in range(3)]
    for e in episodes:
        sink.write(e)
    sink.close()
    dst = tools.filter_dataset(root, tmp_path / "banana", objects=["banana"])
    dataset = load(dst)
    assert dataset.num_episodes == 1 and read_jsonl(dst / "meta" / EPISODES_FILE)[0]["episode_index"] == 2
    item = dataset[1]
    assert np.array_equal(decode_depth_mm(item["observation.depth.drone_own"]), episodes[2].frames["depth/drone_own"][1])
    assert item["observation.images.drone_own"].shape == (3, 128, 128)


def test_a_merge_frees_the_parts_copy_and_new_parts_are_appended(tmp_path):
    """A merged dataset keeps no second copy in its parts (it once kept half its size there): each part keeps its
    records (a resume skips those episodes), and later parts are appended to the merged dataset."""
    root = tmp_path / "ds"
    sink = DatasetSink(root, SPEC, keep=None, part_size=2)
    for i in range(4):
        sink.write(episode(i))
    sink.close()
    assert tools.clean_parts(root) == 0  # the merge already freed them
    parts = sorted((root / ".aerobench" / "parts").iterdir())
    assert all(sorted(p.name for p in part.iterdir()) == ["aerobench_records.jsonl"] for part in parts)
    assert_aligned(root, range(4))

    resumed = DatasetSink(root, SPEC, keep=None, part_size=2)
    assert resumed.done_indices() == {0, 1, 2, 3}
    for i in range(6):
        resumed.write(episode(i))
    resumed.close()
    rows = assert_aligned(root, range(6))
    assert [r["episode_index"] for r in rows] == list(range(6))


def test_join_puts_every_episode_of_several_datasets_in_one(sharded_root, tmp_path):
    failures = tools.filter_dataset(sharded_root, tmp_path / "failures", outcomes=["F", "T"])
    joined = tools.join_datasets([sharded_root, failures], tmp_path / "joined")
    rows = assert_aligned(joined, [*EPISODES, 1, 3, 5])  # each row still describes its episode, renumbered
    first = sorted(read_jsonl(sharded_root / "meta" / EPISODES_FILE), key=lambda r: r["dataset_episode_index"])
    assert [r["episode_index"] for r in rows] == [r["episode_index"] for r in first] + [1, 3, 5]  # in order
    assert dataset_info(joined)["counts"]["outcome"] == {"S": 3, "F": 4, "T": 2}
    meta = json.loads((joined / "meta" / "aerobench.json").read_text())
    assert [s["root"] for s in meta["sources"]] == [str(sharded_root), str(failures)] and "parts" not in meta
    assert meta["generation"]["setting"] == "TidyHouse"  # what BC reads the task state version from

    with pytest.raises(ValueError, match="at least two"):
        tools.join_datasets([sharded_root], tmp_path / "one")
    with pytest.raises(ValueError, match="not empty"):
        tools.join_datasets([sharded_root, failures], joined)
    with pytest.raises(ValueError, match="holds no merged aerobench dataset"):
        tools.join_datasets([sharded_root, tmp_path], tmp_path / "nothing")
    cameras = tmp_path / "cameras"
    sink = DatasetSink(cameras, SPEC, keep=None, part_size=8)
    sink.write(episode(0, cameras=True, steps=2))
    sink.close()
    with pytest.raises(ValueError, match="differ in features observation.depth.drone_front"):
        tools.join_datasets([sharded_root, cameras], tmp_path / "mixed")
    assert not (tmp_path / "one").exists() and not (tmp_path / "mixed").exists()
