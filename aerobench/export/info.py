"""What a dataset folder holds: `dataset_info` (episode counts, frames, features) and `format_info` (as a table).

`aerobench dataset info DIR` prints `format_info(dataset_info(DIR))`; the dataset card (`card`) is written from
`dataset_info`. Reads the folder through `layout` only, so the writer and the merge can write the card.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

from .features import LEROBOT_DEFAULT_KEYS
from .layout import (
    EPISODES_FILE,
    RECORDS_FILE,
    bookkeeping_dir,
    completed_parts,
    part_has_dataset,
    part_rows,
    read_dataset_meta,
    read_jsonl,
)

COUNT_FIELDS = ("setting", "skill", "object", "outcome", "mode")


def lerobot_info(root: Path) -> dict | None:
    """LeRobot's meta/info.json of the dataset at `root`, None when it has none (not merged yet)."""
    path = root / "meta" / "info.json"
    return json.loads(path.read_text()) if path.is_file() else None


def feature_table(features: dict) -> dict[str, dict]:
    """Each of aerobench's features (not LeRobot's own index columns) with its dtype and shape."""
    return {
        key: {"dtype": ft["dtype"], "shape": list(ft["shape"])}
        for key, ft in features.items()
        if key not in LEROBOT_DEFAULT_KEYS
    }


def dataset_info(root: str | Path) -> dict:
    """What a dataset folder holds: episode counts by setting, skill, object, outcome and mode, frames, features.

    Counts describe the LeRobot dataset's episodes (root/meta/aerobench_episodes.jsonl); before any merge they come
    from the parts' records (the episodes that will be in the dataset). "processed" counts every episode the
    generation handled, kept or not; "unmerged_parts" counts committed parts not yet in the merged dataset.
    """
    root = Path(root)
    info = lerobot_info(root)
    parts = completed_parts(root)
    processed = [row for part in parts for row in part_rows(part)]
    if not processed:
        processed = read_jsonl(bookkeeping_dir(root) / RECORDS_FILE)
    if info is None and not bookkeeping_dir(root).is_dir():
        raise ValueError(f"{root} is neither a LeRobot dataset (no meta/info.json) nor an aerobench generation folder")
    merged_parts = set((read_dataset_meta(root) or {}).get("parts", []))
    warning = None
    if info is not None:
        episodes = read_jsonl(root / "meta" / EPISODES_FILE)
        frames, features = info["total_frames"], info["features"]
        if len(episodes) != info["total_episodes"]:  # edited by a tool that keeps LeRobot's files only
            warning = (f"meta/{EPISODES_FILE} {'is missing' if not episodes else 'lists other episodes'} (the dataset "
                       f"was edited by a tool that keeps LeRobot's files only, e.g. lerobot-edit-dataset): outcome, "
                       f"mode and object counts are unknown; the per-frame annotation.* columns and the subtask rows "
                       f"(language_persistent) are intact")
            episodes = _episodes_from_data(root, info["total_episodes"])
    else:
        episodes = [row for row in processed if row["in_dataset"]]
        frames = sum(int(row["steps"]) for row in episodes)
        part_info = next((lerobot_info(p) for p in parts if part_has_dataset(p)), None)
        features = part_info["features"] if part_info else {}
        info = part_info or {}
    return {
        "root": str(root),
        "warning": warning,
        "merged": (root / "meta" / "info.json").is_file(),
        "episodes": len(episodes),
        "frames": int(frames),
        "fps": info.get("fps"),
        "robot_type": info.get("robot_type"),
        "processed": len(processed),
        "not_kept": sum(1 for row in processed if not row["in_dataset"]),
        "parts": len(parts),
        "unmerged_parts": sum(1 for p in parts if p.name not in merged_parts),
        "counts": {name: dict(Counter(str(row[name]) for row in episodes).most_common()) for name in COUNT_FIELDS},
        "features": feature_table(features),
    }


def _episodes_from_data(root: Path, total: int) -> list[dict]:
    """Per episode, what its data columns still say (the skill of its first annotated frame); "unknown" elsewhere."""
    import pyarrow.parquet as pq

    from ..envs.tasks import SKILLS
    from .features import ANNOTATION_SKILL

    first: dict[int, int] = {}
    for path in sorted((root / "data").rglob("*.parquet")):
        table = pq.read_table(path, columns=["episode_index", ANNOTATION_SKILL])
        for episode, skill in zip(table.column(0).to_pylist(), table.column(1).to_pylist()):
            first.setdefault(int(episode), int(skill))
    return [{"setting": "unknown", "skill": SKILLS[first[e]] if 0 <= first.get(e, -1) < len(SKILLS) else "unknown",
             "object": "unknown", "outcome": "unknown", "mode": "unknown"} for e in range(total)]


def format_info(info: dict) -> str:
    """`dataset_info`'s dict as a readable plain-text table."""
    lines = [*([f"warning: {info['warning']}"] if info.get("warning") else []),
        f"dataset   {info['root']}  ({'merged' if info['merged'] else 'not merged yet'})",
        f"episodes  {info['episodes']}   frames {info['frames']}   fps {info['fps']}   robot {info['robot_type']}",
        f"processed {info['processed']} ({info['not_kept']} not kept)   "
        f"parts {info['parts']} ({info['unmerged_parts']} not merged)",
        "",
    ]
    width = max(len(name) for name in COUNT_FIELDS)
    for name in COUNT_FIELDS:
        counts = info["counts"][name]
        cells = "   ".join(f"{value} {n}" for value, n in counts.items()) or "-"
        lines.append(f"{name:<{width}}  {cells}")
    if info["features"]:
        lines += ["", "features"]
        key_width = max(len(key) for key in info["features"])
        for key, ft in info["features"].items():
            shape = "x".join(str(n) for n in ft["shape"])
            lines.append(f"  {key:<{key_width}}  {ft['dtype']:<8} {shape}")
    return "\n".join(lines)
