"""`aerobench train perceive-act`: put a camera network (the perception) and a state controller into one
`perceive_act` policy folder (`policies.perceive_act`).

The perception is an `aerobench train bc` checkpoint with an auxiliary head (`--aux-fields F`); the controller a
`bc` or `ppo` checkpoint whose task-state inputs are all among F. Nothing is trained here: the two checkpoints are
copied and the head's target scale (the mean and spread of F over the perception's training frames) is recorded, from
its checkpoint where it has one or else from its training dataset (checkpoints before that scale was saved); with
`--depth-z`, each object's grasp height below the surface its goal keypoint lands on is measured on demonstrations.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import torch

from ..envs.objects import OBJECTS
from ..envs.observations import STATE_FIELDS, field_slices
from ..envs.platforms import get_platform
from ..policies.camera_input import as_network_input, camera_frames_in_body
from ..policies.learned import CHECKPOINT_FILES, STD_FLOOR, load_actor, read_config, resolve_checkpoint
from ..policies.perceive_act import CONTROLLER, PERCEIVE_ACT_FORMAT, PERCEPTION, keypoint_goal_offset
from ..policies.provenance import STARTS_FILE, dataset_starts, read_starts, write_starts

DEPTH_Z_WITHIN_M = 0.05  # the calibration's frames: the grasp point within this of the tool centre point
DEPTH_Z_MIN_FRAMES = 5  # an object with fewer such frames gets no calibration (the head's vertical estimate stays)


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
        "help": "farther away, the first of these cameras that sees the goal (by --keypoint-gate-m and "
                "--keypoint-spread-max; e.g. drone_front,drone_own)"})
    keypoint_gate_m: float = field(default=0.2, metadata={
        "help": "a far camera sees the goal where its keypoint puts it within this distance (m) of the head's "
                "estimate (0: no such gate)"})
    keypoint_spread_max: float | None = field(default=None, metadata={
        "help": "a camera sees the goal where its goal keypoint's attention spread is under this (image "
                "half-widths; about 0.3: docs/experiments.md), the near camera at any distance (default: no such gate)"})
    goal_filter_rate: float | None = field(default=None, metadata={
        "help": "average the goal's estimates in the env frame until a grasp, each new one with this weight (the goal "
                "does not move before it is grasped; default: no filter, or 1 with --goal-memory)"})
    goal_memory: bool = field(default=False, metadata={
        "help": "only the cameras' sightings of the goal update the goal filter, which holds the last one between "
                "them by the airframe's own motion (needs --keypoint-camera)"})
    depth_z: bool = field(default=False, metadata={
        "help": "near the grasp, the vertical offset from the --keypoint-camera's depth plus a per-object height "
                "measured on demonstrations (--depth-z-dataset) instead of the head's estimate"})
    depth_z_dataset: str | None = field(default=None, metadata={
        "help": "... measured on this camera dataset (default: the perception's training dataset; another one's "
                "starts count as the policy's training starts)"})
    depth_z_frames: int = field(default=3000, metadata={
        "help": "... on each object's leading episodes within this many frames"})
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


def perception_frames(perception: Path, dataset: str, **overrides) -> tuple[dict, dict, torch.Tensor]:
    """A dataset's frames as the perception was trained to read them (`train.bc.load_demos`: history, egocentric
    fields, instruction, cameras at its size, no augmentation), labelled `aux` = `goal_pos_body` then `goal_pos`; the
    facts; and each frame's raw proprio state `(T, 19)` holding its attitude (what back-projection reads), else 0."""
    from .bc import checkpoint_config, load_demos

    base = {"dataset": dataset, "out": tempfile.mkdtemp(), "progress": False, **overrides}
    data, facts = load_demos(checkpoint_config(perception, **base, aux_fields=("goal_pos_body", "goal_pos")))
    raw = load_demos(checkpoint_config(perception, **base, blind=True, goal_keypoint_weight=0.0, aux_fields=(),
                                       ego_fields=(), state_fields=("orientation_6d",), history=1, instruction=False,
                                       film=False))[0]["state"]
    state = torch.zeros(len(raw), sum(n for _, n in STATE_FIELDS))
    state[:, field_slices(STATE_FIELDS)["orientation_6d"]] = raw
    return data, facts, state


def depth_z_offsets(perception: Path, dataset: str, camera: str, frames: int, batch: int = 256) -> dict[str, float]:
    """Per object (by name), the median of its grasp point's height minus the surface under `camera`'s goal
    keypoint, over the frames of `dataset` within `DEPTH_Z_WITHIN_M` of the grasp where the camera has depth there
    (its keypoint's attention is often diffuse there, the object filling the view: not gated on it), in the object's
    leading episodes within `frames` frames. On held-out Pick demonstrations it varies 2-9 mm within an object and
    1-9 cm between objects (docs/experiments.md)."""
    _, actor, normalizer = load_actor(perception)
    cameras = read_config(perception)["model"]["cameras"]
    out = {}
    for name in OBJECTS:
        try:
            data, facts, state = perception_frames(perception, dataset, objects=(name,), max_transitions=frames)
        except ValueError:  # no episode of this object (or none within the budget)
            continue
        if "instruction" not in data:
            raise ValueError(f"--depth-z needs a perception that reads the instruction (the object it names); "
                             f"{perception} does not")
        truth = data["aux"][:, :3]
        near = (truth.norm(dim=-1) < DEPTH_Z_WITHIN_M).nonzero()[:, 0]
        if len(near) < DEPTH_Z_MIN_FRAMES:
            continue
        platform = get_platform(facts["robot_type"].removeprefix("aerobench_") if facts.get("robot_type") else "gripper")
        eye, axes, tan_half = camera_frames_in_body(platform, (camera,))
        tcp = torch.tensor(platform.grasp_point_m)
        height = []
        with torch.no_grad():
            for rows in near.split(batch):
                inputs = {"state": normalizer.state(data["state"][rows]), "instruction": data["instruction"][rows],
                          **{c: as_network_input(data[c][rows]) for c in cameras}}
                keypoints: dict[str, torch.Tensor] = {}
                actor.embed(inputs, keypoints)
                offset, depth = keypoint_goal_offset(inputs[camera], keypoints[camera], state[rows], eye[0].float(),
                                                     axes[0].float(), float(tan_half[0]), tcp)
                height.append((truth[rows, 2] - offset[:, 2])[depth > 0])
        height = torch.cat(height) if height else torch.zeros(0)
        if len(height) >= DEPTH_Z_MIN_FRAMES:
            out[name] = round(float(height.median()), 4)
    if not out:
        raise ValueError(f"no object of {dataset} has {DEPTH_Z_MIN_FRAMES} frames near its grasp with depth under "
                         f"{camera}'s keypoint: --depth-z cannot be measured there")
    return out


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
    if config.goal_memory and not config.keypoint_camera:
        raise ValueError("--goal-memory remembers the cameras' sightings of the goal: give --keypoint-camera too")
    if config.keypoint_spread_max is not None and not config.keypoint_spread_max > 0:
        raise ValueError(f"--keypoint-spread-max must be positive, got {config.keypoint_spread_max}")
    if config.goal_filter_rate is not None and not (0.0 < config.goal_filter_rate <= 1.0 and "goal_pos_body" in fields):
        raise ValueError(f"--goal-filter-rate must be in (0, 1] and the perception must estimate goal_pos_body, got "
                         f"{config.goal_filter_rate}")
    if config.depth_z and not config.keypoint_camera:
        raise ValueError("--depth-z reads the depth under the --keypoint-camera's goal keypoint: give it too")
    mean, std = head_scale(perception, config.train_dataset)
    depth_dataset = config.depth_z_dataset or config.train_dataset or seen["train"]["dataset"]
    if config.depth_z and not Path(depth_dataset, "meta", "info.json").is_file():
        raise ValueError(f"--depth-z measures heights on a camera dataset; {depth_dataset} is not one (give "
                         f"--depth-z-dataset)")
    depth_z = depth_z_offsets(perception, depth_dataset, config.keypoint_camera, config.depth_z_frames) \
        if config.depth_z else None
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
    calibration = out / STARTS_FILE  # the starts of the demonstrations the heights were measured on, if not its own
    calibration.unlink(missing_ok=True)
    if depth_z is not None:
        starts = dataset_starts(Path(depth_dataset), source=depth_dataset)
        if not starts.starts <= read_starts(perception).starts:
            write_starts(out, starts)
    (out / "config.json").write_text(json.dumps({
        "format": PERCEIVE_ACT_FORMAT, "algorithm": "perceive_act", "fields": list(fields), "aux_mean": mean,
        "aux_std": std, "keypoint_camera": config.keypoint_camera, "keypoint_range_m": config.keypoint_range_m,
        "far_keypoint_cameras": list(config.far_keypoint_cameras),
        "keypoint_gate_m": config.keypoint_gate_m or None, "keypoint_spread_max": config.keypoint_spread_max,
        "goal_filter_rate": config.goal_filter_rate, "goal_memory": config.goal_memory, "depth_z": depth_z,
        "depth_z_range_m": DEPTH_Z_WITHIN_M,
        "sources": {PERCEPTION: str(config.perception), CONTROLLER: str(config.controller)},
    }, indent=2) + "\n")
    return out
