"""The JSONL record sink: one episode record per line, appended and synced as each episode finishes.

An interrupted run loses at most the episode in flight: on open, a torn last line (the process died mid-write) is
dropped, and `done_indices` tells the runner which episodes to skip. The run's spec is kept beside the records so a
folder holding a different run is refused instead of mixed.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path

from .episode import EpisodeData

RECORDS_FILE = "records.jsonl"
RUN_FILE = "run.json"


def read_records(path: str | Path) -> list[dict]:
    """Rows of a records.jsonl (a torn last line is ignored)."""
    rows = []
    for line in Path(path).read_text().splitlines():
        if not line.strip():
            continue
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:
            break  # only the last line can be torn; nothing after it was acknowledged
    return rows


class RecordSink:
    """Episode records of one run in `root/records.jsonl`; `spec` (JSON-able) must match the folder's run."""

    def __init__(self, root: str | Path, spec: Mapping, recorded_elsewhere: set[int] | frozenset[int] = frozenset()):
        self.root = Path(root)
        self.recorded_elsewhere = set(recorded_elsewhere)  # this run's episodes already in another shard's file
        self.path = self.root / RECORDS_FILE
        spec = json.loads(json.dumps(dict(spec)))
        run_file = self.root / RUN_FILE
        if run_file.exists():
            held = json.loads(run_file.read_text())
            if held != spec:
                diff = sorted(k for k in set(held) | set(spec) if held.get(k) != spec.get(k))
                raise ValueError(f"{self.root} holds a different run (differs in {', '.join(diff)}); "
                                 f"use another --out or delete the folder")
        elif self.root.exists() and any(self.root.iterdir()):
            raise ValueError(f"{self.root} is not empty and holds no aerobench run; use another --out")
        self.root.mkdir(parents=True, exist_ok=True)
        if not run_file.exists():
            tmp = run_file.with_suffix(".tmp")
            tmp.write_text(json.dumps(spec, indent=2, sort_keys=True) + "\n")
            tmp.replace(run_file)
        self.rows = read_records(self.path) if self.path.exists() else []
        self._rewrite_if_torn()

    def _rewrite_if_torn(self) -> None:
        if not self.path.exists():
            return
        text = self.path.read_text()
        clean = "".join(json.dumps(r, sort_keys=True) + "\n" for r in self.rows)
        if text != clean:
            tmp = self.path.with_suffix(".tmp")
            tmp.write_text(clean)
            tmp.replace(self.path)

    def done_indices(self) -> set[int]:
        return {int(r["episode_index"]) for r in self.rows} | self.recorded_elsewhere

    def write(self, episode: EpisodeData) -> None:
        row = episode.record.to_dict()
        if row["episode_index"] in self.done_indices():
            raise RuntimeError(f"episode {row['episode_index']} is already recorded")
        row["extra"] = {k: v for k, v in episode.extra.items()}
        line = json.dumps(row, sort_keys=True, allow_nan=False) + "\n"
        with open(self.path, "a") as f:
            f.write(line)
            f.flush()
            os.fsync(f.fileno())
        self.rows.append(json.loads(line))

    def flush(self) -> None:
        pass  # every write is already synced

    def close(self) -> None:
        pass


def run_record_files(root: str | Path, spec: Mapping) -> list[Path]:
    """Every record file of one sharded run under `root` (its own folder and `shards/*/`, whatever the worker count
    or shard layout it was started with); a folder there holding a different run is refused, not mixed in. `spec`
    is the run's spec without its `shard`."""
    root = Path(root)
    wanted = json.loads(json.dumps({k: v for k, v in dict(spec).items() if k != "shard"}))
    files = []
    for run_file in [root / RUN_FILE, *sorted(root.glob(f"shards/*/{RUN_FILE}"))]:
        if not run_file.is_file():
            continue
        held = {k: v for k, v in json.loads(run_file.read_text()).items() if k != "shard"}
        if held != wanted:
            diff = sorted(k for k in set(held) | set(wanted) if held.get(k) != wanted.get(k))
            raise ValueError(f"{run_file.parent} holds a different run (differs in {', '.join(diff)}); "
                             f"use another --out or delete the folder")
        if (run_file.parent / RECORDS_FILE).is_file():
            files.append(run_file.parent / RECORDS_FILE)
    return files


def unique_records(files: list[Path]) -> list[dict]:
    """The records of `files` by episode index, each episode once (a resumed run whose shard layout changed may hold
    an episode in two shard files; the first recorded is kept)."""
    rows: dict[int, dict] = {}
    for f in files:
        for r in read_records(f):
            rows.setdefault(int(r["episode_index"]), r)
    return [rows[i] for i in sorted(rows)]
