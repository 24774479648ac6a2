"""Camera data generation: where an RGB-D episode's time goes, and the throughput of `aerobench generate` on this machine.

Part 1, one process, one thread (CPU seconds per recorded frame, `time.process_time`, every thread of the process):
- the simulation and the expert with state-only observations;
- the same with the three 128x128 RGB-D cameras (the difference is rendering);
- LeRobot's dataset writer on those episodes (`DatasetSink`: PNG staging, AV1 video encoding, per-episode statistics,
  the depth images, parquet).

Part 2, the user's command: `aerobench generate ... --shard i/K` in K processes at once (K = the cores), once with
`--threads T` for each T of `--threads` (torch's default is one thread per core; aerobench's default is one), the
settings run in turn in one run of this script. It prints episodes and frames per minute per core for each, and the
ratio of the last to the first.

    python bench/camera_generation.py [--skill place] [--episodes 12] [--threads 2,1] [--shards 2]
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
logging.getLogger("mani_skill").setLevel(logging.ERROR)

SETTING = "PrepareGroceries"
SEED = 105
NOISE = 0.05  # the DART noise camera datasets are generated with (docs/experiments.md)


def breakdown(skill: str, episodes: int) -> dict:
    """CPU milliseconds per frame of simulation + expert, rendering, and the dataset writer (one process)."""
    import aerobench.envs  # noqa: F401
    from aerobench.export.sink import DatasetSink
    from aerobench.rollout.episode import EpisodeList
    from aerobench.rollout.runner import RolloutRunner, RolloutSpec
    from aerobench.threads import torch_threads

    with torch_threads(1), tempfile.TemporaryDirectory() as tmp:
        warm = RolloutSpec(setting=SETTING, skills=(skill,), episodes=1, seed=SEED + 1, record_cameras=True)
        RolloutRunner(warm, EpisodeList()).run()  # imports, compiled kernels, the renderer: not per-frame costs
        runs = {}
        for cameras in (False, True):
            spec = RolloutSpec(setting=SETTING, skills=(skill,), episodes=episodes, seed=SEED, record_cameras=cameras,
                               action_noise=NOISE)
            sink = EpisodeList()
            c0 = time.process_time()
            RolloutRunner(spec, sink).run()
            runs[cameras] = (time.process_time() - c0, sink.episodes, spec)
        state_s, state_eps, _ = runs[False]
        camera_s, episodes_data, spec = runs[True]
        frames = sum(e.num_frames for e in episodes_data)
        assert frames == sum(e.num_frames for e in state_eps), "the same episodes with and without cameras"
        sink = DatasetSink(Path(tmp) / "ds", spec.as_dict(), part_size=episodes)
        c0 = time.process_time()
        for episode in episodes_data:
            sink.write(episode)
        sink.close()
        write_s = time.process_time() - c0
    return {"frames": frames, "episodes": len(episodes_data),
            "simulation_and_expert_ms": 1000 * state_s / frames, "rendering_ms": 1000 * (camera_s - state_s) / frames,
            "dataset_writer_ms": 1000 * write_s / frames}


def throughput(skill: str, episodes: int, shards: int, threads: int, root: Path) -> dict:
    """`aerobench generate` in `shards` processes at once with `--threads threads`; merged; wall time and frames."""
    out = root / f"threads{threads}"
    shutil.rmtree(out, ignore_errors=True)
    exe = Path(sys.executable).parent / "aerobench"
    command = [str(exe), "generate", "--setting", SETTING, "--skills", skill, "--episodes", str(episodes),
               "--seed", str(SEED), "--action-noise", str(NOISE), "--threads", str(threads), "--out", str(out)]
    env = {k: v for k, v in os.environ.items() if k != "OMP_NUM_THREADS"}  # torch's own default, unless --threads
    t0 = time.perf_counter()
    procs = [subprocess.Popen(command + ["--shard", f"{i}/{shards}"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              env=env) for i in range(shards)]
    for p in procs:
        _, err = p.communicate()
        if p.returncode:
            raise SystemExit(f"aerobench generate failed:\n{err.decode()[-2000:]}")
    wall = time.perf_counter() - t0
    subprocess.run([str(exe), "dataset", "merge", str(out)], check=True, capture_output=True)
    info = json.loads((out / "meta" / "info.json").read_text())
    return {"threads": threads, "wall_s": wall, "episodes": info["total_episodes"], "frames": info["total_frames"],
            "episodes_per_min_per_core": 60 * info["total_episodes"] / wall / shards,
            "frames_per_min_per_core": 60 * info["total_frames"] / wall / shards}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--skill", default="place")
    parser.add_argument("--episodes", type=int, default=12, help="episodes per throughput run (all shards)")
    parser.add_argument("--breakdown-episodes", type=int, default=2)
    parser.add_argument("--threads", default="2,1", help="the --threads settings to compare, in turn")
    parser.add_argument("--shards", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--no-breakdown", action="store_true")
    args = parser.parse_args()
    if not args.no_breakdown:
        b = breakdown(args.skill, args.breakdown_episodes)
        total = b["simulation_and_expert_ms"] + b["rendering_ms"] + b["dataset_writer_ms"]
        print(f"one process, {b['episodes']} {SETTING} {args.skill} episodes, {b['frames']} frames; CPU ms per frame:")
        for key in ("simulation_and_expert_ms", "rendering_ms", "dataset_writer_ms"):
            print(f"  {key.removesuffix('_ms').replace('_', ' '):24s} {b[key]:6.1f}  ({100 * b[key] / total:.0f}%)")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for threads in (int(t) for t in args.threads.split(",")):
            r = throughput(args.skill, args.episodes, args.shards, threads, Path(tmp))
            rows.append(r)
            print(f"aerobench generate, {args.shards} shards at once, --threads {threads}: {r['episodes']} episodes, "
                  f"{r['frames']} frames in {r['wall_s']:.1f} s: {r['episodes_per_min_per_core']:.2f} episodes and "
                  f"{r['frames_per_min_per_core']:.0f} frames per minute per core")
    if len(rows) > 1:
        print(f"ratio (--threads {rows[-1]['threads']} over --threads {rows[0]['threads']}): "
              f"{rows[-1]['frames_per_min_per_core'] / rows[0]['frames_per_min_per_core']:.2f}x")


if __name__ == "__main__":
    main()
