"""The LeRobot feature dict for an episode's shape, and the frames of an `EpisodeData` in that layout.

Keys follow LeRobot's constants (`observation.images.<camera>`, `observation.state`, `action`); aerobench adds
`observation.depth.<camera>` (packed depth, `aerobench.depth`) and the `annotation.*` columns. docs/datasets.md lists
every column.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_IMAGES, OBS_STATE

from ..depth import encode_depth_mm
from ..envs.observations import ARM_STATE_FIELDS, STATE_DIM, state_field_names, task_state_field_names
from ..envs.platforms import CONTROL_HZ
from ..envs.tasks import SKILLS
from ..rollout.episode import CAMERAS, EVENT_FLAGS, EpisodeData

FPS = CONTROL_HZ  # one dataset frame per control step (20 Hz)
# LeRobot decodes videos with torchcodec when it loads, else pyav; torchcodec needs FFmpeg's shared libraries
# (libavutil 56-60), which a plain Linux machine may not have, and LeRobot then prints their loading traceback on
# every dataset it opens before falling back. aerobench names the decoder that works everywhere instead.
VIDEO_BACKEND = "pyav"
ROBOT_TYPE_PREFIX = "aerobench_"
OBS_DEPTH = "observation.depth"
ANNOTATION_SKILL = "annotation.skill"
ANNOTATION_STAGE = "annotation.stage"
ANNOTATION_PHASE = "annotation.phase"
ANNOTATION_EVENTS = "annotation.events"
IMAGE_NAMES = ["height", "width", "channels"]
IMAGE_HW = (128, 128)  # DESIGN "Observation": 128x128 cameras (the recorded frames' own size wins)
RGB_CHANNELS = 3
FLIGHT_ACTION_NAMES = ("u_x", "u_y", "u_z", "u_psi")
ARM_ACTION_NAMES = ("q_shoulder", "q_elbow", "q_wrist")
GRIPPER_ACTION_NAMES = ("u_g",)
ARM_STATE_DIM = STATE_DIM + sum(n for _, n in ARM_STATE_FIELDS)
NO_SKILL = -1  # a frame outside every skill stage keeps -1 in `annotation.skill`
# Columns LeRobot adds to every dataset itself; they are not part of an aerobench episode's shape.
LEROBOT_DEFAULT_KEYS = ("timestamp", "frame_index", "episode_index", "index", "task_index")


def rgb_key(camera: str) -> str:
    return f"{OBS_IMAGES}.{camera}"


def depth_key(camera: str) -> str:
    return f"{OBS_DEPTH}.{camera}"


def action_names(with_arm: bool) -> list[str]:
    """`[u_x, u_y, u_z, u_psi, (q_shoulder, q_elbow, q_wrist,) u_g]`, the env's action order."""
    return [*FLIGHT_ACTION_NAMES, *(ARM_ACTION_NAMES if with_arm else ()), *GRIPPER_ACTION_NAMES]


def robot_type(platform: str) -> str:
    """LeRobot's `robot_type` for a platform name: `aerobench_gripper` or `aerobench_arm`."""
    return f"{ROBOT_TYPE_PREFIX}{platform}"


def build_features(
    *, with_arm: bool, cameras: Sequence[str] = CAMERAS, image_hw: tuple[int, int] = IMAGE_HW, task_state: bool = True
) -> dict[str, dict]:
    """LeRobot `features` for `LeRobotDataset.create`: cameras (none for a state-only dataset), state, the
    privileged task state (`observation.environment_state`), action, annotations. RGB is "video"; depth is an
    "image" holding the packed 16-bit millimetres."""
    image_shape = (*image_hw, RGB_CHANNELS)
    features: dict[str, dict] = {}
    for camera in cameras:
        features[rgb_key(camera)] = {"dtype": "video", "shape": image_shape, "names": IMAGE_NAMES}
    for camera in cameras:
        features[depth_key(camera)] = {"dtype": "image", "shape": image_shape, "names": IMAGE_NAMES}
    state_names = state_field_names(with_arm)
    features[OBS_STATE] = {"dtype": "float32", "shape": (len(state_names),), "names": state_names}
    if task_state:
        task_names = task_state_field_names(with_arm)
        features[OBS_ENV_STATE] = {"dtype": "float32", "shape": (len(task_names),), "names": task_names}
    names = action_names(with_arm)
    features[ACTION] = {"dtype": "float32", "shape": (len(names),), "names": names}
    features[ANNOTATION_SKILL] = {"dtype": "int64", "shape": (1,), "names": None}
    features[ANNOTATION_STAGE] = {"dtype": "int64", "shape": (1,), "names": None}
    features[ANNOTATION_PHASE] = {"dtype": "int64", "shape": (1,), "names": None}
    features[ANNOTATION_EVENTS] = {"dtype": "float32", "shape": (len(EVENT_FLAGS),), "names": list(EVENT_FLAGS)}
    return features


def _recorded_cameras(frames: dict[str, np.ndarray]) -> tuple[str, ...]:
    rgb = tuple(c for c in CAMERAS if f"rgb/{c}" in frames)
    depth = tuple(c for c in CAMERAS if f"depth/{c}" in frames)
    if rgb != depth or rgb not in ((), CAMERAS):
        raise ValueError(
            f"an episode records all cameras {CAMERAS} (rgb and depth) or none; got rgb {rgb}, depth {depth}"
        )
    return rgb


def episode_features(episode: EpisodeData) -> dict[str, dict]:
    """The feature dict for this episode's shape (arm or not from the state size; cameras or none)."""
    state_dim = episode.frames["state"].shape[-1]
    if state_dim not in (STATE_DIM, ARM_STATE_DIM):
        raise ValueError(f"state has {state_dim} values; expected {STATE_DIM} (gripper) or {ARM_STATE_DIM} (arm)")
    with_arm = state_dim == ARM_STATE_DIM
    action_dim = episode.frames["action"].shape[-1]
    if action_dim != len(action_names(with_arm)):
        raise ValueError(
            f"action has {action_dim} values but the state is that of {'an arm' if with_arm else 'a gripper'} platform"
        )
    cameras = _recorded_cameras(episode.frames)
    image_hw = tuple(episode.frames[f"rgb/{cameras[0]}"].shape[1:3]) if cameras else IMAGE_HW
    return build_features(with_arm=with_arm, cameras=cameras, image_hw=image_hw, task_state="task_state" in episode.frames)


def features_summary(features: dict[str, dict]) -> str:
    """A short description of a feature dict's shape, for one-line mismatch errors."""
    cameras = sum(1 for ft in features.values() if ft["dtype"] == "video")
    return (
        f"state {features[OBS_STATE]['shape'][0]}, action {features[ACTION]['shape'][0]}, "
        f"{'cameras' if cameras else 'no cameras'}"
    )


def features_signature(features: dict[str, dict]) -> dict[str, tuple]:
    """What must agree between two parts of one dataset: each user feature's dtype, shape and names.

    Language columns are left out: the merge adds them to the whole dataset (export/language.py), no episode has them.
    """
    return {
        key: (ft["dtype"], tuple(ft["shape"]), tuple(ft["names"]) if ft.get("names") else None)
        for key, ft in features.items()
        if key not in LEROBOT_DEFAULT_KEYS and ft["dtype"] != "language"
    }


def _global_skill_index(episode: EpisodeData) -> np.ndarray:
    """Map the episode's own skill indices (into `episode.skills`) onto the dataset-wide list `SKILLS`."""
    unknown = [s for s in episode.skills if s not in SKILLS]
    if unknown:
        raise ValueError(f"episode {episode.record.episode_index}: unknown skills {unknown}; known: {SKILLS}")
    lut = np.array([SKILLS.index(s) for s in episode.skills] or [NO_SKILL], dtype=np.int64)
    local = np.asarray(episode.frames["skill"], dtype=np.int64)
    return np.where(local >= 0, lut[np.clip(local, 0, len(lut) - 1)], NO_SKILL)


def episode_frames(episode: EpisodeData, features: dict[str, dict]) -> Iterator[dict]:
    """One LeRobot frame dict per control step (every feature plus "task"), ready for `add_frame`."""
    frames, steps = episode.frames, episode.num_frames
    for name, array in frames.items():
        if len(array) != steps:
            raise ValueError(
                f"episode {episode.record.episode_index}: frames[{name!r}] has {len(array)} rows, action has {steps}"
            )
    skill = _global_skill_index(episode)
    stage = np.asarray(frames["stage"], dtype=np.int64)
    phase = np.asarray(frames["phase"], dtype=np.int64)
    state = np.asarray(frames["state"], dtype=np.float32)
    action = np.asarray(frames["action"], dtype=np.float32)
    events = np.asarray(frames["events"], dtype=np.float32)
    cameras = [c for c in CAMERAS if rgb_key(c) in features]
    for t in range(steps):
        frame = {
            OBS_STATE: state[t],
            ACTION: action[t],
            ANNOTATION_SKILL: skill[t : t + 1],
            ANNOTATION_STAGE: stage[t : t + 1],
            ANNOTATION_PHASE: phase[t : t + 1],
            ANNOTATION_EVENTS: events[t],
            "task": episode.task,
        }
        if OBS_ENV_STATE in features:
            frame[OBS_ENV_STATE] = np.asarray(frames["task_state"][t], dtype=np.float32)
        for camera in cameras:
            frame[rgb_key(camera)] = np.asarray(frames[f"rgb/{camera}"][t], dtype=np.uint8)
            frame[depth_key(camera)] = encode_depth_mm(np.asarray(frames[f"depth/{camera}"][t]))
        yield frame
