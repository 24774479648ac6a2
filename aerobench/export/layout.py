"""A dataset folder's on-disk layout: where each file lives, and how its JSON and JSONL files are read and written.

The writer (`sink`), the merge (`sink.merge_parts`), the dataset card (`card`) and the tools (`info`, `tools`) all read
the folder through this module; it imports none of them, so none of them needs another to find a file.

    root/meta, root/data, root/videos                 the merged LeRobot dataset (after a merge)
    root/meta/aerobench_episodes.jsonl                one record per dataset episode, in episode order
    root/meta/aerobench.json                          spec, skill list, event flags, depth encoding, merged parts
    root/.aerobench/generation.json                   the generation spec (minus "shard")
    root/.aerobench/parts/part-SSS-FFFFFF-LLLLLL/     one finalized part + aerobench_records.jsonl
    root/.aerobench/records.jsonl                     every processed episode's record (rebuilt from the parts)

docs/datasets.md has the full description.
"""

from __future__ import annotations

import json
import os
import re
import uuid
from pathlib import Path

import numpy as np

from .. import tiers
from ..annotation.record import EpisodeRecord
from ..envs.observations import TASK_STATE_VERSION

BOOKKEEPING_DIR = ".aerobench"
GENERATION_FILE = "generation.json"
PARTS_DIR = "parts"
RECORDS_FILE = "records.jsonl"
PART_RECORDS_FILE = "aerobench_records.jsonl"
EPISODES_FILE = "aerobench_episodes.jsonl"  # in root/meta, aligned with the dataset's episode_index
DATASET_META_FILE = "aerobench.json"  # in root/meta
TMP_PREFIX = ".tmp-"
LEROBOT_DIRS = ("data", "videos", "meta")
PART_NAME = re.compile(r"^part-(\d+)-(\d+)-(\d+)$")
# Fields a row adds to an `EpisodeRecord`'s own JSON (part records, records.jsonl, aerobench_episodes.jsonl).
ROW_FIELDS = ("in_dataset", "dataset_episode_index", "task", "skills", "extra", "part")


# ── small file helpers ────────────────────────────────────────────────────────────────────────────────────────


def _jsonable(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON-serializable")


def canonical_json(value):
    """`value` as JSON reads it back (tuples -> lists, numpy scalars -> Python), for comparisons."""
    return json.loads(json.dumps(value, default=_jsonable))


def read_jsonl(path: Path) -> list[dict]:
    """All rows of a JSONL file ([] when it does not exist)."""
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def write_atomic(path: Path, text: str) -> None:
    """Write `text` to `path` through a temporary file and a rename (a reader sees the old file or the new one)."""
    tmp = path.with_name(f"{TMP_PREFIX}{path.name}-{os.getpid()}-{uuid.uuid4().hex[:8]}")
    with open(tmp, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def write_jsonl(path: Path, rows: list[dict]) -> None:
    """Write rows atomically (a reader sees the old file or the new one, never half of one)."""
    write_atomic(path, "".join(json.dumps(r, sort_keys=True, default=_jsonable) + "\n" for r in rows))


def record_from_row(row: dict) -> EpisodeRecord:
    """The `EpisodeRecord` inside a row of records.jsonl / aerobench_episodes.jsonl."""
    return EpisodeRecord.from_dict({k: v for k, v in row.items() if k not in ROW_FIELDS})


# ── bookkeeping paths ─────────────────────────────────────────────────────────────────────────────────────────


def bookkeeping_dir(root: Path) -> Path:
    return Path(root) / BOOKKEEPING_DIR


def parts_dir(root: Path) -> Path:
    return bookkeeping_dir(root) / PARTS_DIR


def _part_key(path: Path) -> tuple[int, int, int]:
    shard, first, last = PART_NAME.match(path.name).groups()
    return int(first), int(shard), int(last)


def completed_parts(root: Path) -> list[Path]:
    """Committed parts in merge order (first episode index, then shard); `.tmp-*` folders are not parts."""
    folder = parts_dir(root)
    if not folder.is_dir():
        return []
    return sorted((p for p in folder.iterdir() if p.is_dir() and PART_NAME.match(p.name)), key=_part_key)


def part_rows(part: Path) -> list[dict]:
    """The records of every episode a part processed (kept or not), each with "in_dataset" and "part"."""
    return [{**row, "part": part.name} for row in read_jsonl(part / PART_RECORDS_FILE)]


def part_has_dataset(part: Path) -> bool:
    return (part / "meta" / "info.json").is_file()


# ── the dataset's meta files ──────────────────────────────────────────────────────────────────────────────────


def read_generation_spec(root: Path) -> dict:
    """root/.aerobench/generation.json: the spec every shard of the dataset shares."""
    generation = bookkeeping_dir(root) / GENERATION_FILE
    if not generation.exists():
        raise ValueError(f"{root} is not an aerobench dataset folder (no {BOOKKEEPING_DIR}/{GENERATION_FILE})")
    return json.loads(generation.read_text())


def read_dataset_meta(root: Path) -> dict | None:
    """root/meta/aerobench.json of a merged (or filtered) dataset, None when there is none."""
    path = Path(root) / "meta" / DATASET_META_FILE
    return json.loads(path.read_text()) if path.exists() else None


def dataset_task_state_version(root: Path) -> int:
    """The `observations.TASK_STATE_VERSION` a dataset was recorded with (1: before versions were recorded)."""
    meta = read_dataset_meta(root)
    if meta is None:
        return TASK_STATE_VERSION  # not written by aerobench's sink: its task state layout was checked by the reader
    return int(meta.get("generation", {}).get("task_state_version", 1))


def input_tiers(features: dict) -> dict[str, list[str]]:
    """Per input tier (`aerobench.tiers`), the dataset's features a policy of that tier may read (the instruction is
    each frame's `task`)."""
    readable = [k for k in features if k.startswith(("observation.", "task"))] + [tiers.INSTRUCTION]
    return {name: [k for k in readable if tier.admits_feature(k)] for name, tier in tiers.TIERS.items()}
