"""Is the expert's gripper release a function of what a policy sees? Per object class of an exported dataset: how
many frames before each release (the last close -> open switch of the gripper command) are labelled "closed" while
their task state is indistinguishable from the release frame's (every task-state value except the skill one-hot
within `--tolerance`). A classifier that reads a few frames cannot tell those frames from the release frame, so
with many of them it learns "keep closed" there (docs/experiments.md, PrepareGroceries Place).

    python bench/release_aliasing.py [DATASET] [--tolerance 1e-3] [--json OUT]

Without DATASET (as `make bench` runs it) it first generates a small state-only PrepareGroceries Place dataset of the
expert (`--episodes`, two object classes, seed 4250), reused on later runs.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aerobench.envs.observations import TASK_STATE_FIELDS, field_slices  # noqa: E402
from aerobench.export import read_jsonl  # noqa: E402

TASK_STATE_KEY = "observation.environment_state"
AFTER_SKILL = field_slices(TASK_STATE_FIELDS)["skill"].stop  # the skill one-hot never changes within an episode
EPISODES_FILE = "meta/aerobench_episodes.jsonl"


def aliased_frames(state: np.ndarray, gripper: np.ndarray, tolerance: float) -> int | None:
    """Closed frames right before the episode's last release whose state is within `tolerance` of the release
    frame's; None when the gripper never opens after being closed."""
    onsets = np.nonzero((gripper[1:] > 0) & (gripper[:-1] < 0))[0]
    if not len(onsets):
        return None
    k = int(onsets[-1]) + 1
    n = 0
    while k - n - 1 >= 0 and gripper[k - n - 1] < 0 and np.abs(state[k - n - 1] - state[k]).max() < tolerance:
        n += 1
    return n


def measure(root: Path, tolerance: float) -> dict:
    import pandas as pd

    files = sorted((root / "data").glob("*/*.parquet"))
    if not files or not (root / EPISODES_FILE).is_file():
        raise ValueError(f"{root} is not an exported aerobench dataset (data/*/*.parquet and {EPISODES_FILE} needed)")
    frames = pd.concat([pd.read_parquet(f, columns=["episode_index", "action", TASK_STATE_KEY]) for f in files])
    objects = {int(r["dataset_episode_index"]): r["object"] for r in read_jsonl(root / EPISODES_FILE)}
    counts: dict[str, list[int]] = defaultdict(list)
    for episode, rows in frames.groupby("episode_index"):
        state = np.stack(rows[TASK_STATE_KEY].to_numpy())[:, AFTER_SKILL:]
        n = aliased_frames(state, np.stack(rows["action"].to_numpy())[:, -1], tolerance)
        if n is not None:
            counts[objects[int(episode)]].append(n)
    return {obj: {"episodes": len(v), "median": float(np.median(v)), "mean": float(np.mean(v)), "max": int(max(v))}
            for obj, v in sorted(counts.items())}


def small_dataset(root: Path, episodes: int) -> Path:
    """Expert Place episodes (tomato soup can, sugar box), state only, all kept; reused when already generated."""
    if not (root / EPISODES_FILE).is_file():
        from aerobench.export.generation import generate
        from aerobench.rollout.runner import RolloutSpec

        generate(RolloutSpec(setting="PrepareGroceries", skills=("place",), episodes=episodes, seed=4250,
                             objects=("tomato_soup_can", "sugar_box"), record_cameras=False), root, keep="all")
    return root


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", nargs="?", default=None,
                        help="an exported aerobench dataset folder (default: generate a small one)")
    parser.add_argument("--episodes", type=int, default=8, help="episodes of the generated dataset")
    parser.add_argument("--out", default="outputs/bench/release_aliasing", help="where the generated dataset goes")
    parser.add_argument("--tolerance", type=float, default=1e-3, help="largest difference of any task-state value")
    parser.add_argument("--json", default=None, help="also write the table to this JSON file")
    args = parser.parse_args(argv)
    try:
        root = Path(args.dataset) if args.dataset else small_dataset(Path(args.out) / "data", args.episodes)
        table = measure(root, args.tolerance)
    except ValueError as e:
        parser.error(str(e))
    print(f"{'object':20s} {'releases':>8s} {'aliased closed frames: median':>30s} {'mean':>6s} {'max':>4s}")
    for obj, row in table.items():
        print(f"{obj:20s} {row['episodes']:8d} {row['median']:30.0f} {row['mean']:6.1f} {row['max']:4d}")
    if args.json:
        Path(args.json).write_text(json.dumps({"tolerance": args.tolerance, "objects": table}, indent=2) + "\n")
    return table


if __name__ == "__main__":
    main()
