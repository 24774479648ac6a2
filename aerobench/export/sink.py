"""`DatasetSink`: the rollout runner's episodes -> a crash-safe LeRobotDataset v3 with aerobench annotations.

LeRobot's writer keeps parquet writers open until `finalize()`, so a process killed mid-write leaves an unreadable
dataset. The sink therefore writes in *parts*: every `part_size` episodes become one complete, finalized LeRobot
dataset in `root/.aerobench/parts/.tmp-...`, renamed into place only when finished (rename is atomic on POSIX).
A killed run loses at most the buffered episodes and the part being written; `done_indices()` reports the committed
ones and the runner skips them. `close()` merges all parts into `root` with LeRobot's `aggregate_datasets`.

The folder's layout and its readers are in `layout` (docs/datasets.md has the full description).
"""

from __future__ import annotations

import json
import os
import shutil
import uuid
from collections.abc import Callable
from contextlib import AbstractContextManager
from pathlib import Path

from ..annotation.record import EpisodeRecord
from ..depth import DEPTH_ENCODING
from ..envs.observations import TASK_STATE_VERSION
from ..envs.tasks import SKILLS
from ..file_lock import exclusive
from ..rollout.episode import EVENT_FLAGS, EpisodeData
from .card import write_dataset_card
from .features import (
    ANNOTATION_SKILL,
    FPS,
    VIDEO_BACKEND,
    episode_features,
    episode_frames,
    features_signature,
    features_summary,
    robot_type,
)
from .language import add_language_columns
from .layout import (
    DATASET_META_FILE,
    EPISODES_FILE,
    GENERATION_FILE,
    LEROBOT_DIRS,
    PART_RECORDS_FILE,
    RECORDS_FILE,
    TMP_PREFIX,
    bookkeeping_dir,
    canonical_json,
    completed_parts,
    input_tiers,
    part_has_dataset,
    part_rows,
    parts_dir,
    read_dataset_meta,
    read_generation_spec,
    read_jsonl,
    write_atomic,
    write_jsonl,
)

MERGE_DIR = "merge"
MERGE_READY = "READY"
LOCK_FILE = "merge.lock"
# A merged part's LeRobot folders are freed meta first: a part without meta/info.json counts as freed, so a crash
# mid-way never looks like a whole part; its records stay (resume reads them).
FREE_ORDER = ("meta", "data", "videos")
SHARD_KEY = "shard"
PART_REPO_ID = "local/aerobench-part"
# Encoding one camera per process pays off only with cores to spare; small machines encode in-process.
PARALLEL_ENCODING_MIN_CPUS = 4
# SVT-AV1 (LeRobot's default RGB encoder) prints a banner per video at its default log level 3; 1 = errors only.
SVT_LOG_LEVEL = "1"


# ── bookkeeping ───────────────────────────────────────────────────────────────────────────────────────────────


def rebuild_records(root: Path) -> list[dict]:
    """Rewrite root/.aerobench/records.jsonl from the parts (a convenience file) and return its rows."""
    rows = [row for part in completed_parts(root) for row in part_rows(part)]
    write_jsonl(bookkeeping_dir(root) / RECORDS_FILE, rows)
    return rows


def _generation_spec(spec: dict) -> dict:
    """The spec every shard of one dataset shares: the spec without its "shard"."""
    return canonical_json({k: v for k, v in spec.items() if k != SHARD_KEY})


def _shard_of(spec: dict) -> tuple[int, int]:
    shard = spec.get(SHARD_KEY)
    if shard is None:
        return 0, 1
    index, count = (int(x) for x in shard)
    if not 0 <= index < count:
        raise ValueError(f"spec shard {shard!r} must be [i, k] with 0 <= i < k")
    return index, count


def open_root(root: Path, spec: dict) -> None:
    """Check that `root` is empty, missing, or already ours with the same spec; create the bookkeeping.

    Raises a one-line ValueError (and touches nothing) when `root` holds something else.
    """
    root = Path(root)
    generation = bookkeeping_dir(root) / GENERATION_FILE
    wanted = _generation_spec(spec)
    if generation.exists():
        held = json.loads(generation.read_text())
        differ = sorted(k for k in set(held) | set(wanted) if held.get(k) != wanted.get(k))
        if differ:
            raise ValueError(
                f"{root} holds a different dataset ({', '.join(differ)} differ); choose another --out or delete it"
            )
        return
    if root.exists() and not root.is_dir():
        raise ValueError(f"{root} is a file, not a dataset folder; choose another --out")
    if root.is_dir() and any(root.iterdir()) and not bookkeeping_dir(root).is_dir():
        raise ValueError(f"{root} is not empty and is not an aerobench dataset; choose another --out or delete it")
    parts_dir(root).mkdir(parents=True, exist_ok=True)
    write_atomic(generation, json.dumps(wanted, indent=2, sort_keys=True) + "\n")


# ── the sink ──────────────────────────────────────────────────────────────────────────────────────────────────


class DatasetSink:
    """An `EpisodeSink` that writes a LeRobotDataset v3 at `root` in crash-safe parts.

    Args:
        root: the dataset folder (created if missing; must be empty, or ours with the same spec).
        spec: the generation spec (setting, skills, seed, episodes, objects, policy, ...), JSON-serializable;
            an optional "shard": [i, k] names this process's shard (shards share `root`; only "shard" may differ).
        keep: which episodes go into the LeRobot dataset (e.g. successes only); every episode's record is kept
            in the bookkeeping regardless. None keeps all. Episodes with zero frames are never in the dataset.
        part_size: episodes per part (the most a crash can lose, and the granularity of resume).
    """

    def __init__(
        self,
        root: str | Path,
        spec: dict,
        keep: Callable[[EpisodeRecord], bool] | None = None,
        part_size: int = 8,
    ):
        if part_size < 1:
            raise ValueError(f"part_size must be >= 1, got {part_size}")
        self.root = Path(root)
        # the task state's meaning goes with the data: a resume by another version is refused (the specs differ),
        # and a policy trained on it reads the task state as it was recorded (policies.inputs)
        self.spec = {"task_state_version": TASK_STATE_VERSION, **spec}
        self.shard, self.num_shards = _shard_of(self.spec)
        self.part_size = part_size
        self._keep = keep
        open_root(self.root, self.spec)
        for leftover in parts_dir(self.root).glob(f"{self._tmp_prefix()}*"):
            shutil.rmtree(leftover, ignore_errors=True)  # a part this shard was writing when it was killed
        self._buffer: list[EpisodeData] = []
        self._done = self.done_indices()
        self._features: dict | None = None  # the feature dict parts are written with (from the first episode)
        self._reference: tuple[dict, str, str] | None = None  # (signature, robot_type, summary) all parts share
        self._load_reference()

    def _tmp_prefix(self) -> str:
        # Shards share `parts/`; each one only ever cleans its own unfinished parts.
        return f"{TMP_PREFIX}{self.shard:03d}-"

    def _load_reference(self) -> None:
        """The shape episodes must have to join this dataset: that of any committed part (or the merged one)."""
        candidates = [p / "meta" / "info.json" for p in completed_parts(self.root) if part_has_dataset(p)]
        candidates.append(self.root / "meta" / "info.json")
        for path in candidates:
            if path.is_file():
                info = json.loads(path.read_text())
                features = info["features"]
                self._reference = (features_signature(features), info["robot_type"], features_summary(features))
                return

    def done_indices(self) -> set[int]:
        """Episode indices in committed parts (of every shard), kept in the dataset or not."""
        return {int(row["episode_index"]) for part in completed_parts(self.root) for row in part_rows(part)}

    def write(self, episode: EpisodeData) -> None:
        """Buffer one episode; every `part_size` episodes are committed as one part. Done episodes are ignored."""
        index = episode.record.episode_index
        if index in self._done or any(e.record.episode_index == index for e in self._buffer):
            return
        if episode.num_frames:  # an initialization failure has no frames: only its record is kept
            self._check_shape(episode)
        self._buffer.append(episode)
        if len(self._buffer) >= self.part_size:
            self.flush()

    def _check_shape(self, episode: EpisodeData) -> None:
        features = episode_features(episode)
        robot = robot_type(episode.record.platform)
        if self._reference is None:
            self._reference = (features_signature(features), robot, features_summary(features))
        signature, reference_robot, summary = self._reference
        if features_signature(features) != signature or robot != reference_robot:
            raise ValueError(
                f"episode {episode.record.episode_index} ({robot}: {features_summary(features)}) does not match "
                f"this dataset ({reference_robot}: {summary})"
            )
        if self._features is None:
            self._features = features

    def flush(self) -> None:
        """Commit the buffered episodes as one part (atomic rename after LeRobot's `finalize`)."""
        if not self._buffer:
            return
        episodes = sorted(self._buffer, key=lambda e: e.record.episode_index)
        self._write_part(episodes)
        self._done |= {e.record.episode_index for e in episodes}
        self._buffer.clear()
        rebuild_records(self.root)

    def close(self, merge: bool | None = None) -> None:
        """Flush, then merge all parts into `root` (default: merge unless this process is one of several shards)."""
        self.flush()
        if merge is None:
            merge = self.num_shards == 1
        if merge:
            merge_parts(self.root)
        else:
            rebuild_records(self.root)

    def _is_kept(self, episode: EpisodeData) -> bool:
        return episode.num_frames > 0 and (self._keep is None or bool(self._keep(episode.record)))

    def _write_part(self, episodes: list[EpisodeData]) -> None:
        first, last = episodes[0].record.episode_index, episodes[-1].record.episode_index
        name = f"part-{self.shard:03d}-{first:06d}-{last:06d}"
        tmp = parts_dir(self.root) / f"{self._tmp_prefix()}{name}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        kept = [e for e in episodes if self._is_kept(e)]
        if kept:
            self._write_lerobot(tmp, kept)
        else:
            tmp.mkdir(parents=True)
        kept_ids = {id(e) for e in kept}
        rows = [
            {
                **e.record.to_dict(),
                "in_dataset": id(e) in kept_ids,
                "task": e.task,
                "skills": list(e.skills),
                "extra": canonical_json(e.extra),
            }
            for e in episodes
        ]
        write_jsonl(tmp / PART_RECORDS_FILE, rows)
        os.rename(tmp, parts_dir(self.root) / name)

    def _write_lerobot(self, folder: Path, episodes: list[EpisodeData]) -> None:
        from lerobot.datasets.lerobot_dataset import LeRobotDataset  # heavy import, only when writing

        has_video = any(ft["dtype"] == "video" for ft in self._features.values())
        os.environ.setdefault("SVT_LOG", SVT_LOG_LEVEL)  # read by the encoder library when it opens
        robot = robot_type(episodes[0].record.platform)
        dataset = LeRobotDataset.create(
            PART_REPO_ID, FPS, self._features, root=folder, robot_type=robot, use_videos=has_video,
            video_backend=VIDEO_BACKEND,
        )
        parallel = (os.cpu_count() or 1) >= PARALLEL_ENCODING_MIN_CPUS
        for episode in episodes:
            for frame in episode_frames(episode, self._features):
                dataset.add_frame(frame)
            dataset.save_episode(parallel_encoding=parallel)
        dataset.finalize()
        shutil.rmtree(folder / "images", ignore_errors=True)  # LeRobot's emptied per-frame staging folders
        if self.spec.get("language"):
            add_language_columns(folder)  # the phases and stages where LeRobot's own tools keep them


# ── merging parts into root ───────────────────────────────────────────────────────────────────────────────────


def _merge_lock(root: Path) -> AbstractContextManager[None]:
    """One merge at a time per root (shards may finish together)."""
    return exclusive(bookkeeping_dir(root) / LOCK_FILE)


def _swap_in(root: Path, work: Path) -> None:
    """Move the merged dataset in `work` into `root`. Idempotent: a crash anywhere here is finished by a rerun.

    root/meta goes first and comes back last, so `root` never shows new metadata over old data.
    """
    ready = json.loads((work / MERGE_READY).read_text())
    new = work / "dataset"
    if (new / "meta").exists():
        shutil.rmtree(root / "meta", ignore_errors=True)
    for name in ("data", "videos"):
        if (new / name).exists():
            shutil.rmtree(root / name, ignore_errors=True)
            os.rename(new / name, root / name)
        elif name not in ready["dirs"]:
            shutil.rmtree(root / name, ignore_errors=True)
    if (new / "meta").exists():
        os.rename(new / "meta", root / "meta")
    shutil.rmtree(work)


def _recover_merge(root: Path) -> None:
    work = bookkeeping_dir(root) / MERGE_DIR
    if (work / MERGE_READY).exists():
        _swap_in(root, work)  # the build had finished: complete the swap
    elif work.exists():
        shutil.rmtree(work)  # the build had not finished: start over


def _check_unique(rows: list[dict]) -> None:
    seen: dict[int, str] = {}
    for row in rows:
        index = int(row["episode_index"])
        if index in seen:
            raise ValueError(f"episode {index} is in two parts ({seen[index]}, {row['part']}); remove one of them")
        seen[index] = row["part"]


def dataset_meta(spec: dict, parts: list[str], features: dict | None = None) -> dict:
    """The content of root/meta/aerobench.json: what the integer columns and the packed depth mean, and which features
    each input tier may read."""
    return {
        **({"input_tiers": input_tiers(features)} if features is not None else {}),
        "generation": spec,
        "skills": list(SKILLS),
        "skill_feature": ANNOTATION_SKILL,
        "event_flags": list(EVENT_FLAGS),
        "depth_encoding": DEPTH_ENCODING,
        "fps": FPS,
        "parts": parts,
    }


def merge_parts(root: str | Path) -> Path | None:
    """Merge every committed part under root/.aerobench/parts into the LeRobot dataset at `root`.

    Full re-merge from all parts in part order, unless parts were cleaned (`tools.clean_parts`): then the existing
    dataset is the base and only new parts are appended. Builds in root/.aerobench/merge and swaps in; a crash
    during either step is recovered by calling this again. Once the merged dataset is in place, the merged parts'
    LeRobot data is freed (it would double the dataset's size on disk): later merges append new parts to the merged
    dataset. Returns `root`, or None when no episode was kept.
    """
    from lerobot.datasets.aggregate import aggregate_datasets  # heavy import, only when merging

    root = Path(root)
    spec = read_generation_spec(root)
    with _merge_lock(root):
        _recover_merge(root)
        parts = completed_parts(root)
        rows = [row for part in parts for row in part_rows(part)]
        _check_unique(rows)
        names = [p.name for p in parts]
        current = read_dataset_meta(root) if (root / "meta" / "info.json").exists() else None
        if current is not None and current["parts"] == names:
            _free_merged_parts(root, parts, names)  # a crash after the swap left some unfreed
            rebuild_records(root)
            write_dataset_card(root)
            return root  # already up to date
        cleaned = [p for p in parts if not part_has_dataset(p) and any(r["in_dataset"] for r in part_rows(p))]
        if cleaned:
            if current is None or any(p.name not in current["parts"] for p in cleaned):
                raise ValueError(
                    f"{root}: parts {[p.name for p in cleaned]} were cleaned but are not in the merged dataset"
                )
            base = set(current["parts"])
            new_parts = [p for p in parts if p.name not in base]
            sources = [root] + [p for p in new_parts if part_has_dataset(p)]
            episode_rows = read_jsonl(root / "meta" / EPISODES_FILE)
            episode_rows += [r for p in new_parts for r in part_rows(p) if r["in_dataset"]]
        else:
            sources = [p for p in parts if part_has_dataset(p)]
            episode_rows = [r for r in rows if r["in_dataset"]]
        if not sources:
            rebuild_records(root)
            return None
        work = bookkeeping_dir(root) / MERGE_DIR
        aggregate_datasets(
            [PART_REPO_ID] * len(sources), f"local/{root.name}", roots=sources, aggr_root=work / "dataset"
        )
        merged_meta = work / "dataset" / "meta"
        merged_info = json.loads((merged_meta / "info.json").read_text())
        total = merged_info["total_episodes"]
        if total != len(episode_rows):
            raise RuntimeError(f"merged {total} episodes but the parts' records list {len(episode_rows)}")
        out_rows = []
        for index, row in enumerate(episode_rows):
            row = {k: v for k, v in row.items() if k not in ("in_dataset", "part")}
            out_rows.append({**row, "dataset_episode_index": index})
        write_jsonl(merged_meta / EPISODES_FILE, out_rows)
        meta = dataset_meta(spec, names, merged_info["features"])
        write_atomic(merged_meta / DATASET_META_FILE, json.dumps(meta, indent=2) + "\n")
        dirs = [name for name in LEROBOT_DIRS if (work / "dataset" / name).exists()]
        write_atomic(work / MERGE_READY, json.dumps({"dirs": dirs}))
        _swap_in(root, work)
        _free_merged_parts(root, parts, names)
        rebuild_records(root)
        write_dataset_card(root)
    return root


def _free_merged_parts(root: Path, parts: list[Path], merged: list[str]) -> None:
    """Delete the LeRobot folders of the parts in the merged dataset (held under the merge lock)."""
    for part in parts:
        if part.name in merged:
            for name in FREE_ORDER:
                if (part / name).exists():
                    shutil.rmtree(part / name)
