"""How many CPU threads torch uses while aerobench works: one helper that every floor (generation, evaluation,
training) calls, so no lower floor imports the trainers for it."""

from __future__ import annotations

import contextlib

import torch

# One torch thread per process: each core runs its own shard, env or small network, and torch's default (one thread
# per core) oversubscribes the machine as soon as two processes run. Measured on two cores: two camera-generation
# shards 1.7x faster, BC steps up to ~80x faster on a loaded machine (docs/performance.md).
PER_PROCESS_THREADS = 1


@contextlib.contextmanager
def torch_threads(n: int = PER_PROCESS_THREADS):
    """Run with `n` torch CPU threads, then restore the previous count."""
    if not (isinstance(n, int) and n >= 1):
        raise ValueError(f"--threads must be a positive integer, got {n}")
    old = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(old)
