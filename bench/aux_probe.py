"""How well a camera policy's auxiliary head reads the task state it was trained to predict, on demonstrations it never
saw: the error per field, overall and by the distance to the goal (docs/experiments.md, "Policies that see").

A `vision` checkpoint trained with `aerobench train bc --aux-fields F` has a linear head that predicts the task-state
fields F (e.g. `goal_pos_body`, where the grasp point is) from the features its MLP acts on. The policy never reads F;
the head says whether the cameras found what the fields describe. This probe feeds a held-out dataset's frames to the
checkpoint exactly as training did (`train.bc.load_demos`: history, egocentric fields, instruction, cameras at the
checkpoint's size, no augmentation) and compares the head's output with the true fields. The head was trained on
standardized targets; their mean and spread come from the training dataset's task state (`--train-dataset`).

    python bench/aux_probe.py --checkpoint CKPT --dataset HELD_OUT --train-dataset TRAIN   (a blind control: its own checkpoint)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import torch  # noqa: E402

from aerobench.envs.observations import TASK_STATE_FIELDS  # noqa: E402
from aerobench.policies.camera_input import as_network_input  # noqa: E402
from aerobench.policies.learned import load_actor  # noqa: E402
from aerobench.train.bc import BCConfig, checkpoint_config, load_demos  # noqa: E402

DISTANCE_BINS_M = (0.1, 0.3, 1.0)  # |goal_pos| edges: at the goal, the final approach, across the room
KEYPOINT_PX = 64  # image units (-1 to 1) to pixels of the 128-px camera image


def _config(checkpoint: Path, dataset: str) -> BCConfig:
    return checkpoint_config(checkpoint, dataset=dataset, out=tempfile.mkdtemp(), progress=False)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", required=True)
    p.add_argument("--dataset", required=True, help="held-out demonstrations (a camera dataset)")
    p.add_argument("--train-dataset", required=True, help="the checkpoint's training dataset (the targets' scale)")
    p.add_argument("--batch", type=int, default=256)
    args = p.parse_args(argv)
    checkpoint = Path(args.checkpoint)
    config = _config(checkpoint, args.dataset)
    if not config.aux_fields:
        sys.exit(f"{checkpoint} has no auxiliary head (trained without --aux-fields)")
    keypoints = config.goal_keypoint_weight > 0  # its first keypoint per camera was trained onto the goal
    _, actor, normalizer = load_actor(checkpoint)
    train_aux = load_demos(BCConfig(**{**config.__dict__, "dataset": args.train_dataset, "images": True,
                                       "blind": True, "goal_keypoint_weight": 0.0}))[0]["aux"]
    mean, std = train_aux.mean(0), train_aux.std(0, unbiased=False).clamp_min(1e-6)
    data, _ = load_demos(BCConfig(**{**config.__dict__, "aux_fields": (*config.aux_fields, "goal_pos")}))
    width = data["aux"].shape[1] - 3
    truth, goal_distance = data["aux"][:, :width], data["aux"][:, width:].norm(dim=-1)
    cameras = config.cameras if config.images and not config.blind else ()
    states = normalizer.state(data["state"])
    predicted, found = [], {cam: [] for cam in cameras}
    with torch.no_grad():
        for i in range(0, len(states), args.batch):
            batch = {"state": states[i:i + args.batch],
                     **{cam: as_network_input(data[cam][i:i + args.batch]) for cam in cameras}}
            if "instruction" in data:
                batch["instruction"] = data["instruction"][i:i + args.batch]
            kp = {} if keypoints else None
            predicted.append(actor.aux(actor.embed(batch, kp)) * std + mean)
            for cam, k in (kp or {}).items():
                found[cam].append(k[:, [0, k.shape[1] // 2]])
    error = torch.cat(predicted) - truth
    widths = dict(TASK_STATE_FIELDS)
    names = [f"{f}[{j}]" if widths[f] > 1 else f for f in config.aux_fields for j in range(widths[f])]
    edges = (0.0, *DISTANCE_BINS_M, float("inf"))
    out = {"checkpoint": str(checkpoint), "dataset": args.dataset, "frames": len(error), "fields": names,
           "spread_rms": (truth - truth.mean(0)).pow(2).mean(0).sqrt().tolist(),
           "rmse": error.pow(2).mean(0).sqrt().tolist(), "by_goal_distance_m": []}
    for lo, hi in zip(edges[:-1], edges[1:]):
        inside = (goal_distance >= lo) & (goal_distance < hi)
        if inside.any():
            out["by_goal_distance_m"].append({"from": lo, "to": hi, "frames": int(inside.sum()),
                                              "rmse": error[inside].pow(2).mean(0).sqrt().tolist()})
    if keypoints:  # the goal keypoint's error, in pixels of the 128-px camera image, where the goal is in view
        out["goal_keypoint_px"] = {}
        for c, cam in enumerate(cameras):
            seen = data["goal_visible"][:, c]
            miss = (torch.cat(found[cam]) - data["goal_xy"][:, c]).norm(dim=-1) * KEYPOINT_PX
            out["goal_keypoint_px"][cam] = [
                {"from": lo, "to": hi, "frames": int(m.sum()), "median": float(miss[m].median())}
                for lo, hi in zip(edges[:-1], edges[1:]) for m in [seen & (goal_distance >= lo) & (goal_distance < hi)]
                if m.any()]
    print(f"{checkpoint}: {out['frames']} held-out frames of {args.dataset}")
    print("field".ljust(22) + "spread (rms)".rjust(14) + "head error (rms)".rjust(18))
    for name, spread, rmse in zip(names, out["spread_rms"], out["rmse"]):
        print(f"{name:<22}{spread:>14.3f}{rmse:>18.3f}")
    for row in out["by_goal_distance_m"]:
        print(f"|goal| {row['from']:.1f}-{row['to']:.1f} m ({row['frames']} frames): "
              + ", ".join(f"{n} {e:.3f}" for n, e in zip(names, row["rmse"])))
    for cam, rows in out.get("goal_keypoint_px", {}).items():
        print(f"goal keypoint, {cam}: " + ", ".join(f"|goal| {r['from']:.1f}-{r['to']:.1f} m median {r['median']:.1f} px "
                                                    f"({r['frames']} frames)" for r in rows))
    return out


if __name__ == "__main__":
    print(json.dumps(main()))
