"""One holder at a time across processes, by an advisory `flock` on a file (POSIX): merges of dataset parts, and
ahead-of-time kernel builds."""

from __future__ import annotations

import fcntl
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def exclusive(path: Path) -> Iterator[None]:
    """Hold `path`'s lock (the file is made if missing and never removed: removing it would let a waiter and a
    newcomer lock two different files)."""
    with open(path, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
