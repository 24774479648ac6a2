"""`aerobench generate`: a rollout spec's episodes into a LeRobot dataset, in this process or on Ray.

`generate` runs one process's shard (`--shard i/k`) through the crash-safe `DatasetSink`; `generate_on_ray` runs
every shard as a Ray task into the same folder (shared by the workers: a local disk, or NFS-style storage on a
cluster), then merges the shards' parts the way `aerobench dataset merge` does. Both write the same episodes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from ..rollout.episode import EpisodeData
from ..rollout.runner import Progress, RolloutRunner, RolloutSpec
from ..threads import PER_PROCESS_THREADS, torch_threads
from .sink import DatasetSink
from .tools import merge

KEEP_CHOICES = ("success", "all")


def open_sink(spec: RolloutSpec, out: str | Path, keep: str, part_size: int, language: bool = False) -> DatasetSink:
    """The dataset sink of `spec`'s shard at `out` (a ValueError if `out` holds a different generation); `language`:
    also write the phases and stages as LeRobot's `language_persistent` rows (export/language.py)."""
    if keep not in KEEP_CHOICES:
        raise ValueError(f"--keep must be one of {', '.join(KEEP_CHOICES)}, got {keep!r}")
    is_kept = (lambda r: r.outcome == "S") if keep == "success" else None
    spec_dict = {**spec.as_dict(), "keep": keep, **({"language": True} if language else {})}
    return DatasetSink(Path(out), spec_dict, keep=is_kept, part_size=part_size)


def generate(
    spec: RolloutSpec,
    out: str | Path,
    keep: str = "success",
    part_size: int = 8,
    on_episode: Callable[[EpisodeData, Progress], None] | None = None,
    threads: int = PER_PROCESS_THREADS,
    language: bool = False,
) -> Progress:
    """Run (or continue) this shard's episodes into the dataset at `out` with `threads` torch threads; the only shard
    also merges."""
    sink = open_sink(spec, out, keep, part_size, language)
    with torch_threads(threads):
        progress = RolloutRunner(spec, sink, on_episode=on_episode).run()
        sink.close()
    return progress


def _generate_shard(spec: RolloutSpec, out: str, keep: str, part_size: int, language: bool,
                    progress_actor) -> tuple[int, int]:
    """One Ray task: shard `spec.shard` into `out` (not merged); returns (episodes done, successes run now)."""
    from ..rollout.ray_shards import episode_reporter

    progress = generate(spec, out, keep, part_size, on_episode=episode_reporter(progress_actor),  # one task per core
                        language=language)
    return progress.done, progress.successes


def generate_on_ray(
    spec: RolloutSpec,
    out: str | Path,
    keep: str = "success",
    part_size: int = 8,
    address: str | None = None,
    shards: int | None = None,
    on_progress: Callable[[int, int, float], None] | None = None,
    language: bool = False,
) -> Path | None:
    """Every shard of `spec` as a Ray task (default: one per CPU Ray offers), then one merge. Re-running the same
    command continues: each shard skips the episodes already committed. Returns the merged dataset's root (None
    if no episode was kept)."""
    from ..rollout.ray_shards import connect, default_shards, run_shards, shard_gpus

    connect(address)
    k = shards or max(1, min(default_shards(spec.sim_backend), spec.episodes))
    if k < 1:
        raise ValueError(f"--shards must be a positive integer, got {k}")
    open_sink(replace(spec, shard=(0, k)), out, keep, part_size, language)  # refuse another generation's folder now
    run_shards(_generate_shard, [(replace(spec, shard=(i, k)), str(out), keep, part_size, language) for i in range(k)],
               on_progress=on_progress, num_gpus=shard_gpus(spec.sim_backend))
    return merge(out)
