"""Dataset tools: a filtered copy (`filter_dataset`), several datasets as one (`join_datasets`), merging shards'
parts (`merge`) and reclaiming the parts' disk space (`clean_parts`). What a dataset holds is `info`'s.

`aerobench dataset merge DIR` calls `merge(DIR)`; `aerobench dataset join A B --out C` calls
`join_datasets([A, B], C)`.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterable
from pathlib import Path

from ..annotation.record import OUTCOME_CODES
from .features import VIDEO_BACKEND
from .info import feature_table, lerobot_info
from .layout import (
    DATASET_META_FILE,
    EPISODES_FILE,
    LEROBOT_DIRS,
    parts_dir,
    read_dataset_meta,
    read_jsonl,
    write_jsonl,
)
from .sink import merge_parts

FILTERED_REPO_ID = "local/aerobench-source"


def _matches(row: dict, criteria: dict[str, set[str] | None]) -> bool:
    return all(allowed is None or str(row[field]) in allowed for field, allowed in criteria.items())


def _as_set(values: Iterable[str] | None) -> set[str] | None:
    if values is None:
        return None
    return {values} if isinstance(values, str) else {str(v) for v in values}


def filter_dataset(
    src_root: str | Path,
    dst_root: str | Path,
    *,
    outcomes: Iterable[str] | None = None,
    modes: Iterable[str] | None = None,
    skills: Iterable[str] | None = None,
    objects: Iterable[str] | None = None,
) -> Path:
    """Write a new LeRobot dataset at `dst_root` with the episodes of `src_root` that match every given filter.

    A filter left None matches everything; `skills` matches the record's skill (or chain name). The episodes keep
    their order; dst/meta/aerobench_episodes.jsonl holds their rows with `dataset_episode_index` renumbered.
    Uses LeRobot's `delete_episodes` (videos of dropped episodes are cut out and re-encoded).
    """
    from lerobot.datasets.dataset_tools import delete_episodes
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    src, dst = Path(src_root), Path(dst_root)
    info = lerobot_info(src)
    if info is None:
        raise ValueError(f"{src} holds no merged LeRobot dataset (run `aerobench dataset merge {src}` first)")
    criteria = {
        "outcome": _as_set(outcomes),
        "mode": _as_set(modes),
        "skill": _as_set(skills),
        "object": _as_set(objects),
    }
    bad = (criteria["outcome"] or set()) - set(OUTCOME_CODES)
    if bad:
        raise ValueError(f"unknown outcomes {sorted(bad)}; outcomes are {', '.join(OUTCOME_CODES)}")
    rows = sorted(read_jsonl(src / "meta" / EPISODES_FILE), key=lambda r: r["dataset_episode_index"])
    if len(rows) != info["total_episodes"]:
        raise ValueError(f"{src}: {EPISODES_FILE} lists {len(rows)} episodes, the dataset has {info['total_episodes']}")
    selected = [row for row in rows if _matches(row, criteria)]
    chosen = {field: sorted(allowed) for field, allowed in criteria.items() if allowed is not None}
    if not selected:
        raise ValueError(f"no episode of {src} matches {chosen}")
    if dst.exists() and (not dst.is_dir() or any(dst.iterdir())):
        raise ValueError(f"{dst} already exists and is not empty; choose another output folder")
    if dst.exists():
        dst.rmdir()  # LeRobot creates the folder itself and refuses an existing one
    if len(selected) == len(rows):
        dst.mkdir(parents=True)
        for name in LEROBOT_DIRS:
            if (src / name).exists():
                shutil.copytree(src / name, dst / name)
    else:
        keep = {row["dataset_episode_index"] for row in selected}
        drop = [row["dataset_episode_index"] for row in rows if row["dataset_episode_index"] not in keep]
        source = LeRobotDataset(FILTERED_REPO_ID, root=src, video_backend=VIDEO_BACKEND)
        delete_episodes(source, drop, output_dir=dst, repo_id=f"local/{dst.name}")
    write_jsonl(dst / "meta" / EPISODES_FILE, [{**row, "dataset_episode_index": i} for i, row in enumerate(selected)])
    meta = read_dataset_meta(src) or {}
    meta = {k: v for k, v in meta.items() if k != "parts"}
    meta.update(source=str(src), filter=chosen)
    (dst / "meta" / DATASET_META_FILE).write_text(json.dumps(meta, indent=2) + "\n")
    return dst


def join_datasets(sources: Iterable[str | Path], dst_root: str | Path) -> Path:
    """Write one LeRobot dataset at `dst_root` with every episode of `sources`, in order (LeRobot's
    `aggregate_datasets`), e.g. expert demonstrations and the DAgger rounds that followed them.

    dst/meta/aerobench_episodes.jsonl holds the sources' rows with `dataset_episode_index` renumbered, so BC selects
    episodes and reads their starts as from any aerobench dataset. The sources must share their features and task
    state version. Built in a temporary folder and renamed into place: an interrupted join leaves no dataset.
    """
    from lerobot.datasets.aggregate import aggregate_datasets

    srcs, dst = [Path(s) for s in sources], Path(dst_root)
    if len(srcs) < 2:
        raise ValueError("give at least two datasets to join")
    infos = []
    for src in srcs:
        info = lerobot_info(src)
        if info is None or not (src / "meta" / EPISODES_FILE).is_file():
            raise ValueError(f"{src} holds no merged aerobench dataset (run `aerobench dataset merge {src}` first)")
        infos.append(info)
    first = feature_table(infos[0]["features"])
    for src, info in zip(srcs[1:], infos[1:]):
        differ = sorted(k for k in set(first) | set(feature_table(info["features"]))
                        if first.get(k) != feature_table(info["features"]).get(k))
        if differ:
            raise ValueError(f"{src} and {srcs[0]} differ in features {', '.join(differ)}; join datasets recorded "
                             f"alike (the same platform, cameras or not)")
    metas = [read_dataset_meta(src) or {} for src in srcs]
    versions = {int(m.get("generation", {}).get("task_state_version", 1)) for m in metas if m}
    if len(versions) > 1:
        raise ValueError(f"the datasets were recorded with task state versions {sorted(versions)}; regenerate the "
                         f"older ones to join them")
    if dst.exists() and (not dst.is_dir() or any(dst.iterdir())):
        raise ValueError(f"{dst} already exists and is not empty; choose another output folder")
    rows = []
    for src, info in zip(srcs, infos):
        own = sorted(read_jsonl(src / "meta" / EPISODES_FILE), key=lambda r: r["dataset_episode_index"])
        if len(own) != info["total_episodes"]:
            raise ValueError(f"{src}: {EPISODES_FILE} lists {len(own)} episodes, the dataset has {info['total_episodes']}")
        rows += own
    work = dst.with_name(dst.name + ".joining")
    shutil.rmtree(work, ignore_errors=True)
    aggregate_datasets([FILTERED_REPO_ID] * len(srcs), f"local/{dst.name}", roots=srcs, aggr_root=work)
    write_jsonl(work / "meta" / EPISODES_FILE, [{**row, "dataset_episode_index": i} for i, row in enumerate(rows)])
    # "generation" stays the first source's (the setting, platform and task state version they share); each
    # source's own generation spec is kept beside its folder
    meta = {k: v for k, v in metas[0].items() if k != "parts"}
    meta["sources"] = [{"root": str(src), "generation": m.get("generation")} for src, m in zip(srcs, metas)]
    (work / "meta" / DATASET_META_FILE).write_text(json.dumps(meta, indent=2) + "\n")
    if dst.exists():
        dst.rmdir()
    work.rename(dst)
    return dst


def merge(root: str | Path) -> Path | None:
    """Merge whatever committed parts `root` holds (all shards) into the LeRobot dataset at `root`, then free the
    merged parts' copy of the data (`sink.merge_parts`).

    Call after every shard finished (`aerobench dataset merge DIR`), also after copying other machines' parts into
    root/.aerobench/parts. Re-running it is safe and finishes an interrupted merge. Returns None if no episode was
    kept (then only the records are written).
    """
    return merge_parts(root)


def clean_parts(root: str | Path) -> int:
    """Merge (which frees the merged parts' LeRobot data; their records stay, so a resume still skips those episodes)
    and return the bytes freed."""
    root = Path(root)
    before = sum(f.stat().st_size for f in parts_dir(root).rglob("*") if f.is_file())
    merge_parts(root)
    return before - sum(f.stat().st_size for f in parts_dir(root).rglob("*") if f.is_file())
