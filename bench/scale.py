"""Expert demonstrations per minute with 1 and with 2 Ray workers (`aerobench generate --ray`), and their ratio.

The same plan (TidyHouse Pick, state only, the privileged expert, every episode kept) is generated into a fresh
folder by one shard, then by two shards on a local Ray runtime with 2 CPUs. Each shard's worker starts cold (its
imports, env and compiled step: about 10-15 s on the 2-core machine), so two rates are printed: end to end (start-up
and the final merge included) and steady (from the first finished episode to the last).

    python bench/scale.py [--episodes 8] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

from aerobench.export.generation import generate_on_ray  # noqa: E402
from aerobench.rollout.ray_shards import connect  # noqa: E402
from aerobench.rollout.runner import RolloutSpec  # noqa: E402


def rates(spec: RolloutSpec, shards: int) -> tuple[float, float]:
    """(end-to-end, steady) episodes per minute of generating `spec` with `shards` Ray tasks."""
    seen: list[tuple[float, int]] = []
    with tempfile.TemporaryDirectory() as out:
        start = time.monotonic()
        generate_on_ray(spec, out, keep="all", shards=shards,
                        on_progress=lambda done, successes, seconds: seen.append((seconds, done)))
        total = time.monotonic() - start
    first = next((t, d) for t, d in seen if d > 0)
    last = max(seen)
    steady = 60 * (last[1] - first[1]) / (last[0] - first[0]) if last[1] > first[1] else float("nan")
    return 60 * spec.episodes / total, steady


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=8)
    parser.add_argument("--workers", type=int, default=2, help="CPUs of the local Ray runtime (and shards of row 2)")
    args = parser.parse_args()
    connect(None, num_cpus=args.workers)
    spec = RolloutSpec(setting="TidyHouse", skills=("pick",), episodes=args.episodes, record_cameras=False, seed=4100)
    print(f"TidyHouse Pick, state only, expert, {args.episodes} episodes, local Ray runtime with {args.workers} CPUs")
    print(f"{'workers':>8} {'end-to-end ep/min':>18} {'steady ep/min':>14}")
    results = {}
    for k in (1, args.workers):
        results[k] = rates(spec, k)
        print(f"{k:>8} {results[k][0]:>18.1f} {results[k][1]:>14.1f}", flush=True)
    one, many = results[1], results[args.workers]
    print(f"ratio {args.workers} / 1 workers: end-to-end {many[0] / one[0]:.2f}x, steady {many[1] / one[1]:.2f}x")


if __name__ == "__main__":
    main()
