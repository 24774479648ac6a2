"""Is a Place policy's release decision calibrated on demonstrations it never saw? Its gripper head's P(close) on
held-out demonstrations, and the release threshold those demonstrations would choose (docs/experiments.md, "Policies
that see": "Is the release a threshold question?").

A BC policy's gripper head gives P(close) per frame; it opens where P(close) <= a threshold (`model.close_threshold`,
0.5 by default). Per held-out demonstration, up to the expert's release, and per threshold: where the policy would
first open: in the air (the object's bottom more than 2 cm above the goal and off its support: a drop), on the
support, or never; the object's height there, and how many control steps after the expert's release.
The calibrated threshold is the highest at which at most `--max-early` of the demonstrations would let go in the air
(strictly below that quantile of their lowest in-air P(close), rounded down to 0.001); `--out` writes a copy of the
checkpoint with it. These are the expert's states: whether the policy's own set-downs look like them is what a
closed-loop evaluation says.

    python bench/release_calibration.py --checkpoint CKPT --dataset HELD_OUT_PLACE_DEMOS [--max-early 0.05]
        [--thresholds 0.5,0.9] [--whole-episodes] [--out DIR] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import torch  # noqa: E402

from aerobench.policies.camera_input import as_network_input  # noqa: E402
from aerobench.policies.learned import CONFIG_FILE, is_close, load_actor  # noqa: E402
from aerobench.train.bc import checkpoint_config, load_demos  # noqa: E402

ROUND = 1000  # thresholds are written rounded down to 0.001
DROP_M = 0.02  # letting go with the object's bottom higher than this above the goal counts as letting go in the air


@dataclass(frozen=True)
class DemoRelease:
    """One held-out demonstration as the policy's gripper head saw it, up to the expert's release."""

    p_close: torch.Tensor  # per frame
    height: torch.Tensor  # the object's bottom above the placement goal, m
    on_support: torch.Tensor  # bool: the goal support carries the object (task-state progress > 0)
    expert_release: int | None  # the frame of the expert's first open command (None: it never opened)

    def first_open(self, threshold: float) -> int | None:
        """The first frame at which the policy would open at `threshold` (P(close) <= threshold)."""
        opens = (self.p_close <= threshold).nonzero()
        return int(opens[0]) if len(opens) else None


def per_demonstration(p_close: torch.Tensor, progress: torch.Tensor, height: torch.Tensor, close_label: torch.Tensor,
                      segment: torch.Tensor, whole: bool = False) -> list[DemoRelease]:
    """Split a dataset's frames (in order) into demonstrations (`segment`), each up to and including the expert's
    release (`whole`: every frame, also those after it, where the policy sees the fingers open); demonstrations that
    never carry the object closed are left out."""
    demos = []
    for s in segment.unique(sorted=True):
        at = segment == s
        closed = close_label[at] > 0
        if not closed.any():
            continue
        opened = (~closed & (closed.cumsum(0) > 0)).nonzero()  # the first open command after a closed one
        release = int(opened[0]) if len(opened) else None
        end = len(closed) if release is None or whole else release + 1
        demos.append(DemoRelease(p_close[at][:end], height[at][:end], progress[at][:end] > 0, release))
    return demos


def lowest_in_air(demo: DemoRelease, drop_m: float = DROP_M) -> float:
    """The lowest P(close) on the demonstration's frames with the object more than `drop_m` above the goal and off its
    support: at a threshold at or above it, the policy would let go in the air (1.0 if there is no such frame)."""
    air = (demo.height > drop_m) & ~demo.on_support
    return float(demo.p_close[air].min()) if air.any() else 1.0


def release_threshold(lowest: list[float], max_early: float) -> float:
    """The highest threshold (to 0.001) at which at most `max_early` of the demonstrations would let go in the air:
    one does at a threshold t when its `lowest_in_air` P(close) is <= t."""
    if not lowest:
        raise ValueError("no held-out demonstration carries an object: calibrate on a Place dataset")
    if not 0.0 <= max_early < 1.0:
        raise ValueError(f"max_early must be in [0, 1), got {max_early}")
    ordered = sorted(lowest)
    bound = ordered[math.floor(max_early * len(ordered))]  # a threshold must stay strictly below this one's minimum
    return min(max((math.ceil(bound * ROUND) - 1) / ROUND, 1 / ROUND), 1 - 1 / ROUND)


def release_summary(demos: list[DemoRelease], threshold: float, drop_m: float = DROP_M) -> dict:
    """Where the policy would first open at `threshold` on the held-out demonstrations: in the air (higher than
    `drop_m` above the goal, off the support), the object's height there, on the support, never; and the delay
    after the expert's release (control steps; negative: before it)."""
    heights, delays, air, support = [], [], 0, 0
    for d in demos:
        k = d.first_open(threshold)
        if k is None:
            continue
        heights.append(float(d.height[k]))
        air += heights[-1] > drop_m and not bool(d.on_support[k])
        support += bool(d.on_support[k])
        if d.expert_release is not None:
            delays.append(k - d.expert_release)

    def median(values: list) -> float | None:
        return statistics.median(values) if values else None

    return {"threshold": threshold, "demonstrations": len(demos), "early_in_air": air, "released_on_support": support,
            "never": len(demos) - len(heights), "open_height_m_median": median(heights),
            "open_height_m_max": max(heights) if heights else None, "delay_steps_median": median(delays)}


def gripper_probabilities(checkpoint: Path, dataset: str, outcomes: tuple[str, ...] = ("S",)) -> tuple[
        torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict]:
    """P(close) of the checkpoint's gripper head on every frame of `dataset`'s episodes of `outcomes` (fed as training
    fed them: history, egocentric fields, instruction, cameras; no augmentation), with the frames' task-state
    `progress`, the object's bottom height above the goal, the expert's close label and the episode segment; and the
    checkpoint's config."""
    config, actor, normalizer = load_actor(checkpoint)
    if config["model"]["gripper"] != "binary":
        raise ValueError(f"{checkpoint} has a continuous gripper: there is no release threshold to calibrate")
    bc = checkpoint_config(checkpoint, dataset=dataset, out=str(checkpoint), progress=False, outcomes=outcomes,
                           skills=None, aux_fields=("progress", "goal_pos"))
    data, _ = load_demos(bc)
    cameras = bc.cameras if bc.images and not bc.blind else ()
    states = normalizer.state(data["state"])
    logits = []
    with torch.no_grad():
        for i in range(0, len(states), 256):
            batch = {"state": states[i:i + 256], **{c: as_network_input(data[c][i:i + 256]) for c in cameras}}
            if "instruction" in data:
                batch["instruction"] = data["instruction"][i:i + 256]
            logits.append(actor(batch)[:, -1])
    height = -data["aux"][:, 3]  # goal_pos is the goal minus the object's bottom centre
    return (torch.sigmoid(torch.cat(logits)), data["aux"][:, 0], height, is_close(data["action"][:, -1]),
            data["segment"], config)


def calibrate_release(checkpoint: str, dataset: str, max_early: float = 0.05, out: str | None = None,
                      outcomes: tuple[str, ...] = ("S",), thresholds: tuple[float, ...] = (0.5,),
                      whole: bool = False) -> dict:
    """Calibrate `checkpoint`'s release threshold on `dataset` (held-out Place demonstrations); with `out`, write a
    copy of the checkpoint whose config carries the threshold and how it was chosen. Returns the summary, with what
    `thresholds` and the checkpoint's own threshold do on the same demonstrations (`at`)."""
    path = Path(checkpoint)
    if not (path / CONFIG_FILE).is_file():
        raise ValueError(f"no checkpoint at {path} ({CONFIG_FILE} missing); pass RUN/checkpoint of aerobench train bc")
    p_close, progress, height, label, segment, config = gripper_probabilities(path, dataset, outcomes)
    demos = per_demonstration(p_close, progress, height, label, segment, whole)
    threshold = release_threshold([lowest_in_air(d) for d in demos], max_early)
    summary = {**release_summary(demos, threshold), "checkpoint": str(path), "dataset": str(dataset),
               "max_early": max_early, "whole_episodes": whole}
    own = config["model"].get("close_threshold")
    summary["at"] = [release_summary(demos, t) for t in sorted({*thresholds, *([float(own)] if own else [])})]
    if out is not None:
        target = Path(out)
        if target.resolve() == path.resolve():
            raise ValueError("--out must be a new folder: the calibrated checkpoint is a copy")
        shutil.copytree(path, target, dirs_exist_ok=True)
        config["model"]["close_threshold"] = threshold
        config["model"]["release_calibration"] = {k: summary[k] for k in ("dataset", "max_early", "demonstrations",
                                                                           "early_in_air", "released_on_support")}
        (target / CONFIG_FILE).write_text(json.dumps(config, indent=2) + "\n")
        summary["out"] = str(target)
    return summary


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", required=True, help="RUN/checkpoint of aerobench train bc (binary gripper)")
    p.add_argument("--dataset", required=True, help="held-out Place demonstrations (another seed than the training "
                   "data's and than any evaluation's)")
    p.add_argument("--max-early", type=float, default=0.05)
    p.add_argument("--out", help="write a copy of the checkpoint with the calibrated model.close_threshold here")
    p.add_argument("--thresholds", default="0.5", help="also report these thresholds (comma-separated; the "
                   "checkpoint's own is always reported)")
    p.add_argument("--whole-episodes", action="store_true", help="also the frames after the expert's release (where "
                   "the policy sees the fingers open)")
    p.add_argument("--json", help="also write the summary to this file")
    args = p.parse_args(argv)
    try:
        thresholds = tuple(float(t) for t in args.thresholds.split(",") if t)
        summary = calibrate_release(args.checkpoint, args.dataset, args.max_early, args.out, thresholds=thresholds,
                                    whole=args.whole_episodes)
    except ValueError as e:
        sys.exit(f"release_calibration: {e}")
    for row, name in [*((row, "") for row in summary["at"]), (summary, "calibrated ")]:
        print(f"{name}threshold {row['threshold']}: of {row['demonstrations']}, first opens in the air on "
              f"{row['early_in_air']}, on the support on {row['released_on_support']}, never on {row['never']}; "
              f"object {row['open_height_m_median']} m (median) above the goal there, "
              f"{row['delay_steps_median']} steps after the expert (median)")
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=2) + "\n")
    return summary


if __name__ == "__main__":
    main()
