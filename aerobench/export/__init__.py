"""Export: the rollout runner's episodes as a LeRobotDataset v3 with aerobench annotations.

- the depth codec (`aerobench.depth`, re-exported here): uint16 millimetres packed into an RGB uint8 image (R high byte, G low byte, B coarse levels).
- `features`: the LeRobot feature dict for an episode's shape (cameras or state-only, gripper or arm) and the
  per-frame dicts `add_frame` takes.
- `layout`: where each file of a dataset folder lives, and the readers of its JSON / JSONL files.
- `sink`: `DatasetSink`, the crash-safe `EpisodeSink` that writes finalized parts and merges them into the root.
- `info`: `dataset_info` / `format_info`, what a dataset folder holds.
- `card`: the dataset's README.md, written after each merge.
- `tools`: `filter_dataset`, `join_datasets`, `merge` (shards' parts) and `clean_parts`.

docs/datasets.md documents the on-disk layout and every column.
"""

from ..depth import decode_depth_mm, encode_depth_mm
from .features import FPS, build_features, episode_features, robot_type
from .info import dataset_info, format_info
from .layout import read_jsonl, record_from_row
from .sink import DatasetSink
from .tools import clean_parts, filter_dataset, merge

__all__ = [
    "FPS",
    "DatasetSink",
    "build_features",
    "clean_parts",
    "dataset_info",
    "decode_depth_mm",
    "encode_depth_mm",
    "episode_features",
    "filter_dataset",
    "format_info",
    "merge",
    "read_jsonl",
    "record_from_row",
    "robot_type",
]
