"""Where does the pick expert start its descent onto the object, and where does a learned policy stop instead? Per
object class of an exported Pick dataset: the state at the expert's ALIGN -> DESCEND switches (height above the
grasp point, speed, horizontal error) and how many of its pre-descent frames are still (below `--still` m/s above
the object); with `--checkpoint`, the policy's own held-out episodes: which end parked (still, high above the grasp
point, for their last `--window` control steps), where, and how many expert frames lie near that parked state
(the labels BC had for it). The expert descends once settled below 0.04 m/s (`expert.pick`), so it is rarely still
above the object; a policy that decelerates further stops in a state its data never labelled (docs/experiments.md,
PrepareGroceries Pick, round 8).

    python bench/descent_onset.py [DATASET] [--checkpoint CKPT --setting S --objects a,b --episodes N] [--json OUT]

Without DATASET (as `make bench` runs it) it first generates a small state-only PrepareGroceries Pick dataset of the
expert (`--generate`, two object classes, seed 4260), reused on later runs.
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
from aerobench.expert.pick import PickPhase  # noqa: E402
from aerobench.export import read_jsonl  # noqa: E402

TASK_STATE_KEY = "observation.environment_state"
EPISODES_FILE = "meta/aerobench_episodes.jsonl"
SLICES = field_slices(TASK_STATE_FIELDS)
BEFORE_DESCENT = (PickPhase.APPROACH, PickPhase.ALIGN)
NEAR_HEIGHT_M, NEAR_XY_M = 0.01, 0.005  # an expert frame "near" a parked state: within these of its geometry


def geometry(task_state: np.ndarray) -> dict[str, np.ndarray]:
    """Per frame: height of the TCP above the grasp point, horizontal distance to it, airframe speed (task state)."""
    goal = task_state[:, SLICES["goal_pos"]]
    return {"height": -goal[:, 2], "xy": np.linalg.norm(goal[:, :2], axis=1),
            "speed": np.linalg.norm(task_state[:, SLICES["linear_velocity"]], axis=1)}


def read_frames(root: Path):
    import pandas as pd

    files = sorted((root / "data").glob("*/*.parquet"))
    if not files or not (root / EPISODES_FILE).is_file():
        raise ValueError(f"{root} is not an exported aerobench dataset (data/*/*.parquet and {EPISODES_FILE} needed)")
    frames = pd.concat([pd.read_parquet(f, columns=["episode_index", "action", "annotation.phase", TASK_STATE_KEY])
                        for f in files])
    objects = {int(r["dataset_episode_index"]): r["object"] for r in read_jsonl(root / EPISODES_FILE)}
    return frames, objects


def expert_switches(frames, objects: dict[int, str], still: float) -> dict:
    """Per object: the ALIGN -> DESCEND switches (medians of height, speed, horizontal error) and the share of
    pre-descent frames above the object (within 5 cm horizontally) slower than `still`."""
    rows: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for episode, ep in frames.groupby("episode_index"):
        g = geometry(np.stack(ep[TASK_STATE_KEY].to_numpy()))
        phase = ep["annotation.phase"].to_numpy()
        row = rows[objects[int(episode)]]
        k = np.nonzero((phase[1:] == PickPhase.DESCEND) & (phase[:-1] == PickPhase.ALIGN))[0] + 1
        for key in ("height", "speed", "xy"):
            row[key] += g[key][k].tolist()
        above = np.isin(phase, BEFORE_DESCENT) & (g["xy"] < 0.05)
        row["above"].append(int(above.sum()))
        row["still"].append(int((above & (g["speed"] < still)).sum()))
    return {obj: {"switches": len(r["height"]), "height_m": _median(r["height"]), "speed_mps": _median(r["speed"]),
                  "xy_m": _median(r["xy"]), "frames_above": int(sum(r["above"])), "still_frames_above": int(sum(r["still"]))}
            for obj, r in sorted(rows.items())}


def _median(values: list) -> float | None:
    return round(float(np.median(values)), 4) if values else None


def parked(task_state: np.ndarray, window: int, still: float) -> dict | None:
    """The episode's end if its last `window` frames are all slower than `still` with the TCP more than 5 cm above
    the grasp point (hovering instead of descending); else None."""
    g = geometry(task_state[-window:])
    if len(task_state) < window or (g["speed"] >= still).any() or (g["height"] <= 0.05).any():
        return None
    return {"height_m": round(float(g["height"][-1]), 4), "xy_m": round(float(g["xy"][-1]), 4)}


def labelled_frames(frames, objects: dict[int, str]) -> dict[str, np.ndarray]:
    """Every expert frame's geometry, vertical command (normalized action; negative: down) and object class, read
    once for all the parked states a run looks up."""
    table = geometry(np.stack(frames[TASK_STATE_KEY].to_numpy()))
    table["vz"] = np.stack(frames["action"].to_numpy())[:, 2]
    table["object"] = np.array([objects[int(e)] for e in frames["episode_index"].to_numpy()])
    return table


def expert_labels_near(table: dict[str, np.ndarray], state: dict, obj: str, still: float) -> dict:
    """Expert frames (`labelled_frames`) near a parked state (height within 1 cm, horizontal error below 5 mm, speed
    below `still`), of the same object class and of the others, and their mean vertical command."""
    near = (np.abs(table["height"] - state["height_m"]) < NEAR_HEIGHT_M) & (table["xy"] < NEAR_XY_M) & \
        (table["speed"] < still)
    same = table["object"] == obj
    out = {}
    for name, mask in (("same_class", near & same), ("other_classes", near & ~same)):
        vz = table["vz"][mask]
        out[name] = {"frames": int(mask.sum()), "mean_vz_command": round(float(vz.mean()), 3) if len(vz) else None}
    return out


def policy_episodes(checkpoint: str, setting: str, objects: tuple[str, ...], episodes: int, seed: int) -> list:
    """The policy's episodes on held-out starts, in memory (cameras off)."""
    from aerobench.rollout.episode import EpisodeList
    from aerobench.rollout.runner import RolloutRunner, RolloutSpec

    sink = EpisodeList()
    spec = RolloutSpec(setting=setting, skills=("pick",), episodes=episodes, objects=objects, seed=seed,
                       policy="bc", checkpoint=checkpoint, record_cameras=False)
    RolloutRunner(spec, sink).run()
    return sink.episodes


def small_dataset(root: Path, episodes: int) -> Path:
    """Expert Pick episodes (tomato soup can, sugar box), state only, all kept; reused when already generated."""
    if not (root / EPISODES_FILE).is_file():
        from aerobench.export.generation import generate
        from aerobench.rollout.runner import RolloutSpec

        generate(RolloutSpec(setting="PrepareGroceries", skills=("pick",), episodes=episodes, seed=4260,
                             objects=("tomato_soup_can", "sugar_box"), record_cameras=False), root, keep="all")
    return root


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", nargs="?", default=None,
                        help="an exported aerobench Pick dataset folder (default: generate a small one)")
    parser.add_argument("--generate", type=int, default=4, help="episodes of the generated dataset")
    parser.add_argument("--out", default="outputs/bench/descent_onset", help="where the generated dataset goes")
    parser.add_argument("--still", type=float, default=0.01, help="m/s: slower than this is still")
    parser.add_argument("--checkpoint", default=None, help="a state policy checkpoint (bc) to roll out held out")
    parser.add_argument("--setting", default="PrepareGroceries")
    parser.add_argument("--objects", default=None, help="comma-separated object classes for the policy's episodes")
    parser.add_argument("--episodes", type=int, default=4, help="the policy's episodes (per run, over the objects)")
    parser.add_argument("--seed", type=int, default=4000, help="the policy's starts (held out: not a data seed)")
    parser.add_argument("--window", type=int, default=50, help="control steps still at the end to count as parked")
    parser.add_argument("--json", default=None, help="also write the tables to this JSON file")
    args = parser.parse_args(argv)
    try:
        root = Path(args.dataset) if args.dataset else small_dataset(Path(args.out) / "data", args.generate)
        frames, objects = read_frames(root)
    except ValueError as e:
        parser.error(str(e))
    table = expert_switches(frames, objects, args.still)
    print(f"expert ({root}): at the ALIGN -> DESCEND switch, medians")
    print(f"{'object':20s} {'switches':>8s} {'height m':>9s} {'speed m/s':>9s} {'xy mm':>6s} {'still / frames above':>21s}")
    for obj, r in table.items():
        print(f"{obj:20s} {r['switches']:8d} {r['height_m'] or 0:9.3f} {r['speed_mps'] or 0:9.3f} "
              f"{(r['xy_m'] or 0) * 1000:6.1f} {r['still_frames_above']:>10d} / {r['frames_above']}")
    result = {"dataset": str(root), "still_mps": args.still, "expert": table}
    if args.checkpoint:
        chosen = tuple(args.objects.split(",")) if args.objects else None
        rows, table = [], labelled_frames(frames, objects)
        for ep in policy_episodes(args.checkpoint, args.setting, chosen, args.episodes, args.seed):
            stop = parked(ep.frames["task_state"], args.window, args.still) if ep.num_frames else None
            near = expert_labels_near(table, stop, ep.record.object, args.still) if stop else None
            rows.append({"object": ep.record.object, "seed": ep.record.seed, "mode": ep.record.mode,
                         "parked": stop, "expert_frames_near": near})
        print(f"policy {args.checkpoint}: {args.episodes} episodes, seed {args.seed}")
        for r in rows:
            near = r["expert_frames_near"]
            where = (f"parked {r['parked']['height_m']:.3f} m above the grasp point, {r['parked']['xy_m'] * 1000:.1f} mm off; "
                     f"expert frames near it: same class {near['same_class']['frames']} (mean vz command "
                     f"{near['same_class']['mean_vz_command']}), other classes {near['other_classes']['frames']} "
                     f"({near['other_classes']['mean_vz_command']})") if r["parked"] else "not parked"
            print(f"  {r['object']:20s} seed {r['seed']}: {r['mode']}; {where}")
        result["policy"] = {"checkpoint": args.checkpoint, "seed": args.seed, "window": args.window, "episodes": rows}
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
