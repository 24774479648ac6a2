"""`aerobench train perceive-act`: put a camera network (the perception) and a state controller into one
`perceive_act` policy folder (`policies.perceive_act`).

The perception is an `aerobench train bc` checkpoint with an auxiliary head (`--aux-fields F`); the controller a
`bc` or `ppo` checkpoint whose task-state inputs are all among F. Nothing is trained here: the two checkpoints are
copied and the head's target scale (the mean and spread of F over the perception's training frames) is recorded, from
its checkpoint where it has one or else from its training dataset (checkpoints before that scale was saved).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from ..policies.learned import CHECKPOINT_FILES, STD_FLOOR, read_config, resolve_checkpoint
from ..policies.perceive_act import CONTROLLER, PERCEIVE_ACT_FORMAT, PERCEPTION
from ..policies.provenance import STARTS_FILE


@dataclass(frozen=True)
class PerceiveActConfig:
    perception: str = field(metadata={"help": "a camera bc checkpoint (or run folder) with an auxiliary head "
                                              "(aerobench train bc --aux-fields)"})
    controller: str = field(metadata={"help": "a bc / ppo checkpoint (or run folder) whose task-state inputs the "
                                              "head estimates"})
    out: str = field(metadata={"help": "the perceive_act policy folder to write"})
    keypoint_camera: str | None = field(default=None, metadata={
        "help": "near the goal, read its horizontal offset from this camera's goal keypoint and depth (a perception "
                "trained with --goal-keypoint-weight; e.g. drone_hand) instead of the head's estimate"})
    keypoint_range_m: float = field(default=0.3, metadata={
        "help": "... where the head puts the goal within this distance (m)"})
    far_keypoint_cameras: tuple[str, ...] = field(default=(), metadata={
        "help": "farther away, the first of these cameras whose goal keypoint puts the goal within --keypoint-gate-m "
                "of the head's estimate (e.g. drone_front,drone_own)"})
    keypoint_gate_m: float = field(default=0.2, metadata={"help": "... within this distance (m)"})
    goal_filter_rate: float | None = field(default=None, metadata={
        "help": "average the goal's estimates in the env frame until a grasp, each new one with this weight (the goal "
                "does not move before it is grasped; default: no filter)"})
    train_dataset: str | None = field(default=None, metadata={
        "help": "the perception's training dataset, for a checkpoint saved without its head's scale (default: the "
                "dataset its config names)"})


def head_scale(perception: Path, train_dataset: str | None = None) -> tuple[list[float], list[float]]:
    """The auxiliary head's target mean and spread (its fields' own units), as `train_bc` standardized them."""
    saved = json.loads((perception / "normalization.json").read_text())
    if "aux_mean" in saved:
        return saved["aux_mean"], saved["aux_std"]
    from .bc import checkpoint_config, load_demos

    dataset = train_dataset or read_config(perception)["train"]["dataset"]
    if not Path(dataset, "meta", "info.json").is_file():
        raise ValueError(f"{perception} predates the saved auxiliary scale and its training dataset {dataset} is not "
                         f"here; give it with --train-dataset")
    config = checkpoint_config(perception, dataset=dataset, out=str(perception), progress=False, blind=True,
                               goal_keypoint_weight=0.0)  # blind: the targets only, no camera frame is decoded
    aux = load_demos(config)[0]["aux"]
    return aux.mean(0).tolist(), aux.std(0, unbiased=False).clamp_min(STD_FLOOR).tolist()


def compose_perceive_act(config: PerceiveActConfig) -> Path:
    perception = resolve_checkpoint(config.perception)
    controller = resolve_checkpoint(config.controller)
    seen = read_config(perception)
    fields = tuple(seen["data"].get("aux_fields") or ())
    if seen["algorithm"] != "bc" or not fields:
        raise ValueError(f"{perception} has no auxiliary head to estimate with: train it with aerobench train bc "
                         f"--aux-fields FIELDS")
    wanted = tuple(read_config(controller)["model"]["inputs"]["task_fields"])
    missing = [f for f in wanted if f not in fields]
    if missing:
        raise ValueError(f"the controller {controller} reads {', '.join(missing)}, which the perception does not "
                         f"estimate (its --aux-fields: {', '.join(fields)})")
    if config.keypoint_camera:
        train = seen["train"]
        if not train.get("goal_keypoint_weight") or "goal_pos_body" not in fields or \
                any(c not in seen["model"]["cameras"] for c in (config.keypoint_camera, *config.far_keypoint_cameras)):
            raise ValueError("--keypoint-camera (and --far-keypoint-cameras) need a perception that reads them, was "
                             "trained with --goal-keypoint-weight and estimates goal_pos_body")
    if config.goal_filter_rate is not None and not (0.0 < config.goal_filter_rate <= 1.0 and "goal_pos_body" in fields):
        raise ValueError(f"--goal-filter-rate must be in (0, 1] and the perception must estimate goal_pos_body, got "
                         f"{config.goal_filter_rate}")
    mean, std = head_scale(perception, config.train_dataset)
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, source in ((PERCEPTION, perception), (CONTROLLER, controller)):
        target = out / name
        if target.exists():
            shutil.rmtree(target)
        target.mkdir()
        for f in (*CHECKPOINT_FILES, STARTS_FILE):
            if (source / f).is_file():
                shutil.copy2(source / f, target / f)
    (out / "config.json").write_text(json.dumps({
        "format": PERCEIVE_ACT_FORMAT, "algorithm": "perceive_act", "fields": list(fields), "aux_mean": mean,
        "aux_std": std, "keypoint_camera": config.keypoint_camera, "keypoint_range_m": config.keypoint_range_m,
        "far_keypoint_cameras": list(config.far_keypoint_cameras), "keypoint_gate_m": config.keypoint_gate_m,
        "goal_filter_rate": config.goal_filter_rate,
        "sources": {PERCEPTION: str(config.perception), CONTROLLER: str(config.controller)},
    }, indent=2) + "\n")
    return out
