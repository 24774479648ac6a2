"""What the rollout runner hands to a sink: one finished episode, and the sink protocol.

The runner knows no file format: a sink (the JSONL record sink in `rollout.records`, the LeRobot dataset sink in
`export`) receives `EpisodeData` and says which episode indices it already holds, so an interrupted run continues.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..annotation.record import EpisodeRecord

CAMERAS = ("drone_front", "drone_hand", "drone_own")
# Per-frame event flags exported with every frame (names in this order), from the env's info signals.
EVENT_FLAGS = (
    "is_grasped",
    "is_lifted",
    "is_aligned",
    "is_support_contact",
    "is_released",
    "is_gripper_clear",
    "is_nav_reached",
    "is_handle_pinched",
    "is_goal_reached",
    "fail",
    "success",
)


@dataclass
class EpisodeData:
    """One finished episode.

    `frames` holds per-control-step arrays, T rows each (T = record.steps):
    - "state": (T, D) float32 proprioceptive state (`envs.observations`), the observation the action was taken on
    - "action": (T, A) float32 normalized action
    - "rgb/<camera>": (T, 128, 128, 3) uint8 and "depth/<camera>": (T, 128, 128) uint16 millimetres (only when the
      run records cameras)
    - "skill": (T,) int64 index into `skills` of the active stage; "stage": (T,) int64 active stage index;
      "phase": (T,) int64 the expert's phase code (-1 for other policies)
    - "events": (T, len(EVENT_FLAGS)) float32 flags (0/1)
    `task` is the language instruction; `extra` carries per-episode facts for the dataset metadata
    (object mass, instruction, chain, env id).
    """

    record: EpisodeRecord
    frames: dict[str, np.ndarray]
    task: str
    skills: tuple[str, ...]
    extra: dict = field(default_factory=dict)
    signals: dict[str, np.ndarray] = field(default_factory=dict)  # (T,) env info traces a run asked to keep

    @property
    def num_frames(self) -> int:
        return int(self.frames["action"].shape[0]) if "action" in self.frames else 0  # 0: initialization failure


class EpisodeSink(Protocol):
    def done_indices(self) -> set[int]:
        """Episode indices already safely on disk (skipped by the runner)."""

    def write(self, episode: EpisodeData) -> None:
        """Take one finished episode (may buffer; must not lose it once `flush` returned)."""

    def flush(self) -> None:
        """Make everything written so far durable."""

    def close(self) -> None:
        """Flush and finish (e.g. merge the parts of a dataset)."""


class EpisodeList:
    """An `EpisodeSink` that keeps the episodes in memory (`episodes`), for diagnostics that look at a few episodes
    step by step; nothing is written, so nothing resumes."""

    def __init__(self):
        self.episodes: list[EpisodeData] = []

    def done_indices(self) -> set[int]:
        return set()

    def write(self, episode: EpisodeData) -> None:
        self.episodes.append(episode)

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass
