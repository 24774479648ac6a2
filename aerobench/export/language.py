"""The annotation's phases and chain stages as LeRobot's language rows, so LeRobot's own tools keep them.

LeRobot 0.6 stores what a robot is doing in the data files themselves: the `language_persistent` column holds, on
every frame of an episode, that episode's list of persistent rows (`lerobot.datasets.language`), each a state that
became active at its `timestamp` and holds until the next one. aerobench writes one row of style `subtask` per chain
stage and expert phase, e.g. "pick: descend" at 3.45 s, and an empty `language_events` column. Because they are data
columns, `lerobot-edit-dataset` (delete, split, merge) keeps them, where it drops aerobench's own `meta/aerobench*`
files; hierarchical VLAs read them as subtask annotations. The per-frame `annotation.*` columns are kept the same way.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from lerobot.datasets.language import LANGUAGE_EVENTS, LANGUAGE_PERSISTENT, language_feature_info

from ..envs.tasks import SKILLS
from ..expert import phase_name
from .features import ANNOTATION_PHASE, ANNOTATION_SKILL, ANNOTATION_STAGE

SUBTASK = "subtask"


def subtask_text(skill: int, phase: int) -> str:
    """"pick: descend" (an expert phase), or the skill alone where no phase was recorded."""
    name = SKILLS[skill] if 0 <= skill < len(SKILLS) else "between skills"
    label = phase_name(name, phase) if name in SKILLS else None
    return f"{name}: {label}" if label else name


def subtask_rows(timestamp: np.ndarray, skill: np.ndarray, stage: np.ndarray, phase: np.ndarray) -> list[dict]:
    """One episode's persistent rows: a `subtask` row wherever its stage or the expert's phase changes."""
    rows, last = [], None
    for t, k, s, p in zip(timestamp.tolist(), skill.tolist(), stage.tolist(), phase.tolist()):
        if (s, k, p) != last:
            rows.append({"role": "assistant", "content": subtask_text(k, p), "style": SUBTASK, "timestamp": float(t),
                         "camera": None, "tool_calls": None})
            last = (s, k, p)
    return rows


def add_language_columns(root: Path) -> None:
    """Rewrite the data files of the LeRobot dataset at `root` with `language_persistent` (the subtask rows of each
    row's episode) and an empty `language_events`, and declare both in meta/info.json (as `lerobot-annotate` does)."""
    for path in sorted((root / "data").rglob("*.parquet")):
        table = pq.read_table(path)
        columns = {k: table.column(k).to_numpy() for k in
                   ("episode_index", "timestamp", ANNOTATION_SKILL, ANNOTATION_STAGE, ANNOTATION_PHASE)}
        episodes = columns["episode_index"]
        rows_of: dict[int, list[dict]] = {}
        for episode in np.unique(episodes):
            mine = episodes == episode
            rows_of[int(episode)] = subtask_rows(*(columns[k][mine] for k in
                                                   ("timestamp", ANNOTATION_SKILL, ANNOTATION_STAGE, ANNOTATION_PHASE)))
        keep = [n for n in table.column_names if n not in (LANGUAGE_PERSISTENT, LANGUAGE_EVENTS)]
        table = table.select(keep)
        table = table.append_column(LANGUAGE_PERSISTENT, pa.array([rows_of[int(e)] for e in episodes]))
        table = table.append_column(LANGUAGE_EVENTS, pa.array([[] for _ in episodes], type=pa.list_(pa.struct([
            ("role", pa.string()), ("content", pa.string()), ("style", pa.string()), ("camera", pa.string())]))))
        tmp = path.with_suffix(".tmp")
        pq.write_table(table, tmp)
        tmp.replace(path)
    info_path = root / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["features"] = {**info["features"], **language_feature_info()}
    info_path.write_text(json.dumps(info, indent=4))
