"""How well a `perceive_act` policy's perception says where the goal is, on demonstrations it never saw
(docs/experiments.md, "Perceive, then act"): the auxiliary head's estimate of `goal_pos_body` beside each airframe
camera's goal keypoint back-projected through the depth under it (`policies.perceive_act.keypoint_goal_offset`),
as the horizontal and the vertical error (RMS and median, metres) by the distance to the goal; the same for the keypoints whose
attention is concentrated (spread under `--spread-max`: where the camera is sure it sees the goal) with how many
frames they cover, and for what the policy acts on (`fused`, without its goal memory).

    python bench/perceive_probe.py --checkpoint PERCEIVE_ACT_FOLDER --dataset HELD_OUT [--spread-max 0.3] [--out F]

The frames are fed as training fed them (`train.perceive_act.perception_frames`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
os.environ.setdefault("HF_HUB_OFFLINE", "1")

import torch  # noqa: E402

from aerobench.envs.observations import task_state_fields  # noqa: E402
from aerobench.envs.platforms import get_platform  # noqa: E402
from aerobench.policies.camera_input import as_network_input, camera_frames_in_body  # noqa: E402
from aerobench.policies.learned import load_actor  # noqa: E402
from aerobench.policies.perceive_act import PERCEPTION, KeypointGoal, keypoint_goal_offset, read_perceive_act  # noqa: E402,E501
from aerobench.train.perceive_act import perception_frames  # noqa: E402

DISTANCE_BINS_M = (0.05, 0.1, 0.2, 0.3, 0.6, 1.0)  # 0.05: where the depth gives the height (`--depth-z`)


def _errors(estimate: torch.Tensor, truth: torch.Tensor, distance: torch.Tensor, valid: torch.Tensor) -> list[dict]:
    rows, low = [], 0.0
    for high in DISTANCE_BINS_M:
        mask = valid & (distance >= low) & (distance < high)
        if mask.any():
            error = (estimate[mask, :2] - truth[mask, :2]).norm(dim=-1)
            vertical = (estimate[mask, 2] - truth[mask, 2]).abs()
            rows.append({"from": low, "to": high, "frames": int(mask.sum()),
                         "rms_m": float(error.pow(2).mean().sqrt()), "median_m": float(error.median()),
                         "vertical_rms_m": float(vertical.pow(2).mean().sqrt()),
                         "vertical_median_m": float(vertical.median())})
        low = high
    return rows


def _auroc(score: torch.Tensor, positive: torch.Tensor) -> float | None:
    """P(a positive frame scores above a negative one), ties half (the Mann-Whitney statistic); None without both."""
    pos, neg = score[positive], score[~positive]
    if not len(pos) or not len(neg):
        return None
    above = (pos[:, None] > neg[None, :]).float().mean() + 0.5 * (pos[:, None] == neg[None, :]).float().mean()
    return round(float(above), 3)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", required=True, help="an aerobench train perceive-act folder")
    p.add_argument("--dataset", required=True, help="held-out demonstrations (a camera dataset)")
    p.add_argument("--batch", type=int, default=256)
    p.add_argument("--spread-max", type=float, default=None,
                   help="the keypoint spread gate to report (default: the policy's, else 0.3)")
    p.add_argument("--out", help="write the report here (JSON)")
    args = p.parse_args(argv)
    folder, config = read_perceive_act(args.checkpoint)
    perception = folder / PERCEPTION
    train = json.loads((perception / "config.json").read_text())["train"]
    data, facts, state = perception_frames(perception, args.dataset)
    truth, distance = data["aux"][:, :3], data["aux"][:, 3:].norm(dim=-1)
    _, actor, normalizer = load_actor(perception)
    fields = config["fields"]
    sizes = dict(task_state_fields(with_arm=True))
    column = sum(sizes[f] for f in fields[:fields.index("goal_pos_body")])
    mean, std = torch.tensor(config["aux_mean"]), torch.tensor(config["aux_std"])
    platform = get_platform(facts["robot_type"].removeprefix("aerobench_") if facts.get("robot_type") else "gripper")
    cameras = [c for c in train["cameras"] if next(m for m in platform.cameras if m.uid == c).link == "airframe"]
    eye, axes, tan_half = camera_frames_in_body(platform, tuple(cameras))
    tcp = torch.tensor(platform.grasp_point_m)
    fusion = KeypointGoal.from_config(platform, config)
    spread_max = args.spread_max or config.get("keypoint_spread_max") or 0.3
    head, seen, fused = [], {c: ([], []) for c in cameras}, []
    sure, spread = {c: [] for c in cameras}, {c: [] for c in cameras}
    states = normalizer.state(data["state"])
    with torch.no_grad():
        for i in range(0, len(states), args.batch):
            batch = {"state": states[i:i + args.batch],
                     **{c: as_network_input(data[c][i:i + args.batch]) for c in train["cameras"]}}
            if "instruction" in data:
                batch["instruction"] = data["instruction"][i:i + args.batch]
            keypoints: dict[str, torch.Tensor] = {}
            spreads: dict[str, torch.Tensor] = {}
            head.append((actor.aux(actor.embed(batch, keypoints, spreads)) * std + mean)[:, column:column + 3])
            if fusion is not None:  # what the policy acts on
                fused.append(fusion.fuse(head[-1], batch, keypoints, state[i:i + args.batch], spreads)[0])
            for j, c in enumerate(cameras):
                offset, depth = keypoint_goal_offset(batch[c], keypoints[c], state[i:i + args.batch], eye[j].float(),
                                                     axes[j].float(), float(tan_half[j]), tcp)
                seen[c][0].append(offset)
                seen[c][1].append(depth)
                sure[c].append(spreads[c][:, 0] < spread_max)
                spread[c].append(spreads[c][:, 0])
    every = torch.ones(len(truth), dtype=torch.bool)
    report = {"checkpoint": str(folder), "dataset": args.dataset, "frames": len(truth),
              "head": _errors(torch.cat(head), truth, distance, every),
              "keypoint": {c: _errors(torch.cat(o), truth, distance, torch.cat(d) > 0) for c, (o, d) in seen.items()},
              "spread_max": spread_max,
              "keypoint_concentrated": {c: _errors(torch.cat(o), truth, distance, (torch.cat(d) > 0) &
                                                   torch.cat(sure[c])) for c, (o, d) in seen.items()}}
    if fused:
        report["fused"] = _errors(torch.cat(fused), truth, distance, every)
    if "goal_visible" in data:  # the same where the goal is in the camera's view (the label's frames)
        visible = dict(zip(train["cameras"], data["goal_visible"].unbind(1)))
        report["keypoint_in_view"] = {c: _errors(torch.cat(o), truth, distance, (torch.cat(d) > 0) & visible[c])
                                      for c, (o, d) in seen.items()}
        # how well a concentrated attention says the goal is in view (1: always, 0.5: no better than chance)
        report["spread_auroc_goal_in_view"] = {c: _auroc(-torch.cat(spread[c]), visible[c]) for c in cameras}
    text = json.dumps(report, indent=2)
    if args.out:
        Path(args.out).write_text(text + "\n")
    print(text)
    return report


if __name__ == "__main__":
    main(sys.argv[1:])
