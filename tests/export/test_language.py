"""Phases and chain stages as LeRobot's `language_persistent` subtask rows: written with every part, merged, read by
`LeRobotDataset`, and kept by LeRobot's own editing tools (which drop aerobench's meta files: `dataset info` says so
in one line and counts what the data still holds)."""

import numpy as np
import pytest

from aerobench.export import DatasetSink, dataset_info, format_info
from aerobench.export.language import subtask_rows, subtask_text
from aerobench.rollout.runner import RolloutRunner, RolloutSpec
from aerobench.threads import torch_threads


def test_a_row_starts_wherever_the_stage_or_the_experts_phase_changes():
    t = np.arange(6) * 0.05
    rows = subtask_rows(t, np.array([0, 0, 0, 2, 2, 1]), np.array([0, 0, 0, 1, 1, 2]), np.array([0, 0, 2, 0, 0, -1]))
    assert [(r["content"], r["timestamp"]) for r in rows] == [
        ("pick: approach", 0.0), ("pick: descend", 0.1), ("nav: fly", pytest.approx(0.15)),
        ("place", pytest.approx(0.25))]
    assert {r["style"] for r in rows} == {"subtask"} and subtask_text(1, 4) == "place: open"


def test_the_rows_survive_lerobots_episode_deletion_and_dataset_info_says_what_was_lost(tmp_path):
    from lerobot.datasets.dataset_tools import delete_episodes
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = tmp_path / "ds"
    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=2, objects=("tuna_fish_can",), seed=2,
                       record_cameras=False, max_steps=60)
    sink = DatasetSink(root, {**spec.as_dict(), "keep": "all", "language": True})
    with torch_threads(1):
        RolloutRunner(spec, sink).run()
    sink.close()
    before = LeRobotDataset("local/ds", root=root, video_backend="pyav")
    second = [r["content"] for r in before[before.meta.episodes[1]["dataset_from_index"]]["language_persistent"]]
    assert second[0] == "pick: approach" and len(second) >= 2
    edited = delete_episodes(before, episode_indices=[0], output_dir=tmp_path / "edited", repo_id="local/edited")
    rows = edited[0]["language_persistent"]
    assert [r["content"] for r in rows] == second  # the kept episode's subtask rows, as they were
    info = dataset_info(tmp_path / "edited")
    assert info["episodes"] == 1 and info["counts"]["skill"] == {"pick": 1} and info["counts"]["outcome"] == {"unknown": 1}
    first_line = format_info(info).splitlines()[0]
    assert first_line.startswith("warning: meta/aerobench_episodes.jsonl is missing") and "language_persistent" in first_line
    assert dataset_info(root)["warning"] is None
