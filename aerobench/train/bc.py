"""`aerobench train bc`: behaviour cloning on an exported aerobench LeRobotDataset (CleanRL style, one file).

Spec, "Skill Policy Learning": imitate the continuous expert actions of *successful* demonstrations by minimizing the
mean squared error between predicted and normalized actions. The episodes come from the dataset's annotation
(`meta/aerobench_episodes.jsonl`, outcome "S" by default). The inputs are named fields of `observation.state`, of
what the policy computes from it in its heading frame (`policies.egocentric`) and of `observation.environment_state`
(`policies.inputs.InputSpec`; default: the whole task state, no proprio field), optionally with a short history and
the instruction; the image variant adds RGB-D cameras (`observation.images.<cam>`, `observation.depth.<cam>`, decoded
once per dataset by `camera_frames`, shifted at random while training). The gripper is an open/close command: by
default a classification head (binary cross-entropy on "close", with the frames where the command switches
weighted up, since they are a few hundred of tens of thousands) beside the MSE of the continuous flight (and arm)
dimensions.

`--inputs vision` trains for the `vision` tier (`aerobench.tiers`): no task state field, and by default the
egocentric proprio fields, actions in the heading frame and the instruction (docs/experiments.md, "Policies that
see"); a field outside the tier is refused. `--blind` is a camera policy's blind control: the same network and
training with its cameras blanked.

Read top to bottom: config -> demonstrations -> normalization -> networks -> loop (log, checkpoint) -> checkpoint.
Batches are drawn from a generator seeded by (seed, step), so a resumed run draws exactly the batches an
uninterrupted one would: resuming from step N to 2N gives the same weights as one run of 2N steps.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import torch
from torch.nn import functional as F

from .. import tiers
from ..envs.observations import STATE_DIM, TASK_STATE_VERSION, task_state_field_names, task_state_fields
from ..envs.platforms import get_platform
from ..envs.tasks import SKILLS
from ..export.features import VIDEO_BACKEND
from ..export.layout import dataset_task_state_version
from ..policies.camera_input import DEPTH_STEP_M, as_network_input, random_shift
from ..policies.egocentric import to_heading_frame, yaw_of
from ..policies.inputs import ALL_TASK_FIELDS, InputSpec
from ..policies.instruction import instruction_tokens
from ..policies.learned import (
    CAMERA_ENCODERS,
    CAMERAS,
    GRIPPER_MODES,
    STD_FLOOR,
    Normalizer,
    is_close,
    load_weights,
    make_actor,
    model_features,
    model_spec,
    model_tier,
    normalization_stats,
    read_config,
    recover_checkpoint,
    save_checkpoint,
)
from ..policies.provenance import TrainingStarts, dataset_starts
from ..threads import torch_threads
from .camera_frames import camera_frames
from .common import ScalarLog, check_resumable, config_dict, load_train_state, seed_everything
from .goal_pixels import goal_pixels, shifted, unoccluded

OUTCOMES = ("S", "F", "T", "I")
BATCH_SEED_STRIDE = 1_000_003  # batch generator seed = seed * stride + step: distinct streams per seed
EPISODES_FILE = "meta/aerobench_episodes.jsonl"
STATE_KEY, ACTION_KEY, TASK_STATE_KEY = "observation.state", "action", "observation.environment_state"
STAGE_KEY, PHASE_KEY = "annotation.stage", "annotation.phase"
# Options that may change when a run is resumed: the budget, the bookkeeping cadence, and `out` (a run folder may be
# moved).
RESUMABLE_CHANGES = ("steps", "save_every", "log_every", "progress", "threads", "out", "close_threshold")
# What a `vision`-tier policy reads by default (`--inputs vision`): its flight state in its own heading frame, its
# fingers, the yaw turned since the start (the place holds the heading it began with), and the instruction; it acts
# in its heading frame (policies.egocentric). docs/experiments.md, "Policies that see", measures the choices.
VISION_EGO_FIELDS = ("velocity_heading", "angular_velocity_body", "gravity_body_xy", "height", "yaw_since_start",
                     "finger_position", "finger_velocity")
ARM_EGO_FIELDS = ("arm_position", "arm_velocity")
INSTRUCTION_DIM = 32  # the instruction's embedding width (a bag of hashed words, policies.instruction)


@dataclass
class BCConfig:
    dataset: str = field(default=None, metadata={"help": "exported aerobench dataset folder (LeRobotDataset root)"})
    out: str = field(default=None, metadata={"help": "run folder: checkpoint/, scalars.jsonl"})
    steps: int = field(default=10_000, metadata={"help": "gradient steps in total (a resumed run continues to this)"})
    seed: int = field(default=0, metadata={"help": "seed of the network init and the batch order"})
    images: bool = field(default=False, metadata={"help": "image variant: add the three RGB-D cameras"})
    state_fields: tuple[str, ...] = field(default=(), metadata={"help": "proprio state fields to read "
                                          "(envs.observations.STATE_FIELDS, e.g. finger_position)"})
    task_fields: tuple[str, ...] | None = field(default=None, metadata={"help": "task state fields to read "
                                                "(observation.environment_state; default: all of the platform's)"})
    history: int = field(default=3, metadata={"help": "input frames: the current one and history-1 before it "
                         "(the expert waits for the drone to settle before it descends, closes or opens)"})
    gripper: str = field(default="binary", metadata={"help": "gripper head: binary (open/close classification) "
                         "or continuous (regressed with the other dimensions)"})
    close_threshold: float = field(default=0.5, metadata={"help": "binary gripper head: the policy keeps the "
                                   "gripper closed while P(close) exceeds this (checkpoint model.close_threshold; a "
                                   "high one opens earlier in a release the head learned late, docs/experiments.md)"})
    gripper_weight: float = field(default=1.0, metadata={"help": "weight of the gripper's classification loss"})
    onset_weight: float = field(default=10.0, metadata={"help": "weight of the frames where the expert's gripper "
                                "command switches (in the classification loss)"})
    phase_onset_weight: float = field(default=1.0, metadata={"help": "weight, in the flight (and arm) MSE, of the "
                                      "frames where the expert's phase has just switched (e.g. align -> descend), "
                                      "from annotation.phase; 1: no weighting"})
    batch_size: int = field(default=256, metadata={"help": "frames per gradient step"})
    learning_rate: float = field(default=3e-4, metadata={"help": "Adam learning rate"})
    hidden: tuple[int, ...] = field(default=(256, 256), metadata={"help": "MLP hidden sizes"})
    outcomes: tuple[str, ...] = field(default=("S",), metadata={"help": "episode outcomes to train on (spec: S)"})
    objects: tuple[str, ...] | None = field(default=None, metadata={"help": "train on the episodes of these object "
                                            "classes only (default: every class; e.g. a class left out)"})
    skills: tuple[str, ...] | None = field(default=None, metadata={"help": "train on the frames of these skill stages "
                                           "only (a chain's data: one network per stage, given to eval as "
                                           "--checkpoint pick=A,place=B; default: every frame)"})
    max_transitions: int | None = field(default=None, metadata={"help": "a data budget: train on the leading selected "
                                        "episodes, in dataset order, whose frames total at most this (default: all)"})
    image_size: int = field(default=64, metadata={"help": "camera images are reduced to this many pixels a side"})
    inputs: str | None = field(default=None, metadata={"help": "the input tier to train for (aerobench.tiers): "
                               "vision (cameras, proprio, instruction: no task state field, egocentric proprio and "
                               "heading-frame actions by default) or privileged; a field outside it is refused "
                               "(default: the tier of what the options read)"})
    cameras: tuple[str, ...] | None = field(default=None, metadata={"help": "the cameras an image policy reads "
                                            "(default: drone_front,drone_hand,drone_own)"})
    ego_fields: tuple[str, ...] | None = field(default=None, metadata={"help": "proprio-derived fields in the heading "
                                               "frame (policies.egocentric; default: none, or --inputs vision's)"})
    action_frame: str | None = field(default=None, metadata={"help": "world (the env's) or heading (forward, left; "
                                     "turned into the world frame when acting); default: world, or heading for "
                                     "--inputs vision"})
    instruction: bool | None = field(default=None, metadata={"help": "read the language instruction (default: only "
                                     "with --inputs vision)"})
    blind: bool = field(default=False, metadata={"help": "a blind control: the image policy's network with its "
                        "cameras blanked, in training and when it acts"})
    shift: int = field(default=4, metadata={"help": "random-shift augmentation of camera images, in pixels (0: off)"})
    camera_encoder: str = field(default="shared", metadata={"help": "shared (one CNN for every camera) or separate"})
    feature_dim: int = field(default=64, metadata={"help": "features per camera"})
    encoder_head: str = field(default="flatten", metadata={"help": "a camera CNN's head: flatten (a linear layer over "
                              "its maps) or keypoints (spatial softmax: where things are in the image)"})
    film: bool = field(default=False, metadata={"help": "condition the camera CNN on the instruction (FiLM: a scale "
                       "and shift per channel), so it can look for the object the instruction names"})
    cnn_channels: tuple[int, ...] = field(default=(16, 32, 32), metadata={"help": "channels of the camera CNN's "
                                          "stride-2 convolutions"})
    aux_fields: tuple[str, ...] = field(default=(), metadata={"help": "task state fields the network learns to "
                                        "predict from its input features beside the actions (an auxiliary loss, at "
                                        "training time only: the policy never reads them, so its tier is unchanged), "
                                        "e.g. goal_pos_body: where the marked goal is, seen by a vision policy"})
    aux_weight: float = field(default=1.0, metadata={"help": "weight of the auxiliary loss (--aux-fields)"})
    goal_noise_m: float = field(default=0.0, metadata={"help": "train on goal_pos_body read off by an offset drawn per "
                                "frame, N(0, sigma^2) per axis (m), the same in its history: a controller for a "
                                "perception's estimate (aerobench train perceive-act), whose error is a bias, not "
                                "jitter; 0: off"})
    goal_keypoint_weight: float = field(default=0.0, metadata={"help": "train each camera's first keypoint to sit on "
                                        "the skill's goal point in its image (train.goal_pixels; a training-time "
                                        "label, needs --encoder-head keypoints), with this weight; 0: off"})
    save_every: int = field(default=1_000, metadata={"help": "checkpoint every N steps (and at the end)"})
    log_every: int = field(default=50, metadata={"help": "log scalars every N steps"})
    repo_id: str = field(default="local/aerobench", metadata={"help": "LeRobot repo id of the local dataset"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})
    threads: int = field(default=1, metadata={"help": "torch CPU threads (1 is fastest for these small networks)"})

    def __post_init__(self):
        if not self.dataset or not self.out:
            raise ValueError("BCConfig needs dataset=DIR (an exported aerobench dataset) and out=DIR")
        self.hidden, self.outcomes = tuple(self.hidden), tuple(self.outcomes)
        self.state_fields = tuple(self.state_fields)
        self.task_fields = None if self.task_fields is None else tuple(self.task_fields)
        self.objects = None if self.objects is None else tuple(self.objects)
        if self.objects is not None and not self.objects:
            raise ValueError("--objects needs at least one object class (leave it out to train on every class)")
        self.skills = None if self.skills is None else tuple(self.skills)
        if self.skills is not None and (not self.skills or set(self.skills) - set(SKILLS)):
            raise ValueError(f"--skills must name skills of {', '.join(SKILLS)}, got {','.join(self.skills) or 'none'}")
        if self.gripper not in GRIPPER_MODES:
            raise ValueError(f"--gripper must be one of {', '.join(GRIPPER_MODES)}, got {self.gripper!r}")
        if self.inputs is not None:
            tiers.get_tier(self.inputs)
        vision = self.inputs == "vision"
        if self.task_fields is None and vision:
            self.task_fields = ()
        self.ego_fields = tuple(self.ego_fields) if self.ego_fields is not None else (VISION_EGO_FIELDS if vision else ())
        self.action_frame = self.action_frame or ("heading" if vision else "world")
        self.instruction = vision if self.instruction is None else self.instruction
        self.cameras = tuple(self.cameras) if self.cameras is not None else CAMERAS
        unknown = [c for c in self.cameras if c not in CAMERAS]
        if unknown or not self.cameras:
            raise ValueError(f"--cameras must name cameras of {', '.join(CAMERAS)}, got {','.join(self.cameras) or 'none'}")
        if self.blind and not self.images:
            raise ValueError("--blind blanks the cameras of an image policy: add --images")
        if self.camera_encoder not in CAMERA_ENCODERS:
            raise ValueError(f"--camera-encoder must be one of {', '.join(CAMERA_ENCODERS)}, got {self.camera_encoder!r}")
        if self.shift < 0 or self.feature_dim < 1:
            raise ValueError("--shift must not be negative and --feature-dim must be positive")
        self.aux_fields = tuple(self.aux_fields)
        bad = [f for f in self.aux_fields if f not in ALL_TASK_FIELDS]
        if bad:
            raise ValueError(f"--aux-fields must name task state fields ({', '.join(ALL_TASK_FIELDS)}), got {bad}")
        if not self.goal_noise_m >= 0 or (self.goal_noise_m and "goal_pos_body" not in (self.task_fields or ())):
            raise ValueError(f"--goal-noise-m must be >= 0 and needs goal_pos_body in --task-fields, got "
                             f"{self.goal_noise_m}")
        if self.aux_weight < 0:
            raise ValueError(f"--aux-weight must not be negative, got {self.aux_weight}")
        if self.goal_keypoint_weight < 0 or (self.goal_keypoint_weight > 0 and (
                not self.images or self.blind or self.encoder_head != "keypoints")):
            raise ValueError(f"--goal-keypoint-weight needs a non-negative weight, --images without --blind and "
                             f"--encoder-head keypoints, got {self.goal_keypoint_weight}")
        if self.phase_onset_weight < 1:
            raise ValueError(f"--phase-onset-weight must be at least 1, got {self.phase_onset_weight}")
        if not 0.0 < self.close_threshold < 1.0 or (self.close_threshold != 0.5 and self.gripper != "binary"):
            raise ValueError(f"--close-threshold must be between 0 and 1 and needs --gripper binary, got "
                             f"{self.close_threshold}")
        if self.gripper_weight < 0 or self.onset_weight < 1:
            raise ValueError("--gripper-weight must not be negative and --onset-weight must be at least 1")
        for name in ("steps", "batch_size", "save_every", "log_every", "image_size", "threads"):
            if not (isinstance(getattr(self, name), int) and getattr(self, name) > 0):
                raise ValueError(f"--{name.replace('_', '-')} must be a positive integer, got {getattr(self, name)}")
        if self.max_transitions is not None and not (isinstance(self.max_transitions, int) and self.max_transitions > 0):
            raise ValueError(f"--max-transitions must be a positive integer, got {self.max_transitions}")
        if not self.learning_rate > 0:
            raise ValueError(f"--learning-rate must be positive, got {self.learning_rate}")
        bad = [o for o in self.outcomes if o not in OUTCOMES]
        if bad or not self.outcomes:
            raise ValueError(f"unknown outcomes {bad}; valid: {', '.join(OUTCOMES)} (S = successful demonstrations)")
        if not self.hidden or min(self.hidden) < 1:
            raise ValueError(f"--hidden needs positive sizes, e.g. 256,256; got {self.hidden}")
        spec = self.input_spec(with_arm=True)  # unknown field names and a bad history fail here
        if self.inputs is not None:  # reading outside the declared tier: refused before any data is read
            tiers.check_features(model_features(self.model(spec, 1, 1)), self.inputs, "this bc config")

    def input_spec(self, with_arm: bool, task_state_version: int = TASK_STATE_VERSION) -> InputSpec:
        """What the policy reads on this platform from a task state of that version (`task_fields=None`: all of it;
        `--inputs vision`'s egocentric fields gain the arm's on the arm platform)."""
        layout = task_state_fields(with_arm, task_state_version)
        task = self.task_fields if self.task_fields is not None else tuple(n for n, _ in layout)
        ego = self.ego_fields + (ARM_EGO_FIELDS if with_arm and self.ego_fields == VISION_EGO_FIELDS else ())
        return InputSpec(state_fields=self.state_fields, task_fields=task, history=self.history,
                         task_state_version=task_state_version, ego_fields=ego, instruction=self.instruction,
                         action_frame=self.action_frame)

    def model(self, inputs: InputSpec, state_dim: int, action_dim: int) -> dict:
        """The checkpoint's model spec for these inputs and sizes."""
        return model_spec(state_dim, action_dim, self.hidden, inputs, self.cameras if self.images else (),
                          self.image_size, tuple(self.cnn_channels), feature_dim=self.feature_dim, gripper=self.gripper,
                          blind=self.blind, camera_encoder=self.camera_encoder, encoder_head=self.encoder_head,
                          instruction_dim=INSTRUCTION_DIM if inputs.instruction else 0,
                          aux_dim=sum(dict(task_state_fields(with_arm=True))[f] for f in self.aux_fields),
                          film=self.film)


# ── demonstrations ────────────────────────────────────────────────────────────────────────────────────────────────


def select_episodes(root: Path, outcomes: tuple[str, ...], objects: tuple[str, ...] | None = None) -> list[int]:
    """Dataset episode indices whose annotated outcome is one of `outcomes` (and object one of `objects`)."""
    from ..export import read_jsonl

    path = root / EPISODES_FILE
    if not path.is_file():
        raise ValueError(f"{root} has no {EPISODES_FILE}: BC reads an aerobench export (aerobench generate --out DIR, "
                         f"merged) whose annotations name each episode's outcome")
    rows = read_jsonl(path)
    if objects is not None:
        unknown = sorted(set(objects) - {r["object"] for r in rows})
        if unknown:
            raise ValueError(f"{root} has no episode of {', '.join(unknown)}; its objects: "
                             f"{', '.join(sorted({r['object'] for r in rows}))}")
    return [int(r["dataset_episode_index"]) for r in rows
            if r["outcome"] in outcomes and (objects is None or r["object"] in objects)]


def within_budget(episodes: list[int], frame_episode: torch.Tensor, max_transitions: int) -> list[int]:
    """The leading `episodes` (in their order) whose frames total at most `max_transitions`; `frame_episode` holds
    the episode index of every frame of the dataset."""
    lengths = torch.bincount(frame_episode.long())
    kept, total = [], 0
    for e in episodes:
        total += int(lengths[e]) if e < len(lengths) else 0
        if total > max_transitions:
            break
        kept.append(e)
    return kept


def checkpoint_config(checkpoint: Path, **overrides) -> BCConfig:
    """The `BCConfig` a bc checkpoint was trained with (its config's `train`), with `overrides` (e.g. another dataset
    to feed it, as the probes and the release calibration do)."""
    train = read_config(Path(checkpoint))["train"]
    return BCConfig(**{**{k: v for k, v in train.items() if k in BCConfig.__dataclass_fields__}, **overrides})


def goal_noise(sigma_m: float, inputs: InputSpec, width: int):
    """`rows -> (len(rows), width)`: an offset of goal_pos_body per row, N(0, sigma_m^2) per axis, in every history
    frame (`BCConfig.goal_noise_m`)."""
    columns = inputs.task_columns("goal_pos_body", width)

    def draw(rows: torch.Tensor) -> torch.Tensor:
        noise = torch.zeros(len(rows), width)
        offset = torch.randn(len(rows), 3) * sigma_m
        noise[:, columns] = offset.repeat(1, inputs.history)
        return noise
    return draw


def load_demos(config: BCConfig) -> tuple[dict[str, torch.Tensor], dict]:
    """All frames of the selected episodes in memory: `state` (the selected inputs with history), `action` (in the
    policy's action frame), the instruction's word ids, and (image variant) one uint8 `(T, 4, s, s)` tensor per camera;
    plus facts about them (episodes, frames, robot type)."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    root = Path(config.dataset)
    if not (root / "meta" / "info.json").is_file():
        raise ValueError(f"no LeRobot dataset at {root} (meta/info.json missing); export one with aerobench generate")
    episodes = select_episodes(root, config.outcomes, config.objects)
    if not episodes:
        raise ValueError(f"{root} has no episode with outcome {'/'.join(config.outcomes)} to train on")
    ds = LeRobotDataset(config.repo_id, root=root, video_backend=VIDEO_BACKEND)
    if config.images and not config.blind:
        missing = [c for c in config.cameras if f"observation.images.{c}" not in ds.features]
        if missing:
            raise ValueError(f"{root} has no camera features ({', '.join(missing)}); export with cameras or drop --images")
    with_arm = ds.features[STATE_KEY]["shape"][0] > STATE_DIM
    version = dataset_task_state_version(root)
    inputs = config.input_spec(with_arm, version)
    columns = ["index", "episode_index", STATE_KEY, ACTION_KEY] + (["task_index"] if inputs.instruction else [])
    if inputs.reads_task_state:
        if TASK_STATE_KEY not in ds.features:
            raise ValueError(f"{root} has no {TASK_STATE_KEY} (exported by an older aerobench); re-export it, or "
                             f"train on proprio fields alone (--task-fields '' --state-fields ...)")
        if ds.features[TASK_STATE_KEY]["names"] != task_state_field_names(with_arm, version):
            raise ValueError(f"{root}'s {TASK_STATE_KEY} has another layout than this aerobench's task state "
                             f"(exported by an older aerobench); re-export it with aerobench generate")
        columns.append(TASK_STATE_KEY)
    for option, needed in (("--skills", config.skills is not None), ("--aux-fields", bool(config.aux_fields)),
                           ("--goal-keypoint-weight", config.goal_keypoint_weight > 0)):
        if needed and TASK_STATE_KEY not in columns:
            if TASK_STATE_KEY not in ds.features:
                raise ValueError(f"{root} has no {TASK_STATE_KEY} for {option} (exported by an older aerobench); "
                                 f"re-export it, or leave out {option}")
            columns.append(TASK_STATE_KEY)
    columns += [STAGE_KEY] if STAGE_KEY in ds.features else []
    if config.phase_onset_weight != 1:
        if PHASE_KEY not in ds.features:
            raise ValueError(f"{root} has no {PHASE_KEY} (exported by an older aerobench); leave out "
                             f"--phase-onset-weight")
        columns.append(PHASE_KEY)
    table = ds.hf_dataset.select_columns(columns).with_format("torch")[:]
    if config.max_transitions is not None:
        episodes = within_budget(episodes, table["episode_index"], config.max_transitions)
        if not episodes:
            raise ValueError(f"--max-transitions {config.max_transitions} is below the first episode's length; "
                             f"raise it or leave it out")
    chosen = torch.isin(table["episode_index"], torch.tensor(episodes)).nonzero()[:, 0]
    all_segments = stage_segments(table["episode_index"], table.get(STAGE_KEY))
    segment = all_segments[chosen]
    state = table[STATE_KEY][chosen]
    starts = segment_starts(all_segments)[chosen]  # each frame's stage (episode) first frame, as the policy resets
    frames = inputs.frame(state, table[TASK_STATE_KEY][chosen] if inputs.reads_task_state else None,
                          table[STATE_KEY][starts])
    action = table[ACTION_KEY][chosen].float()
    if inputs.action_frame == "heading":
        action = to_heading_frame(action, yaw_of(state.float()))
    data = {"state": inputs.stack_episodes(frames, segment), "action": action, "segment": segment,
            "index": table["index"][chosen]}
    if config.aux_fields:  # training targets only: read from the task state, never given to the network
        aux = InputSpec(task_fields=config.aux_fields, task_state_version=version)
        data["aux"] = aux.frame(state, table[TASK_STATE_KEY][chosen])
    if inputs.instruction:
        tasks = ds.meta.tasks  # task string -> task_index
        text = {int(i): str(task) for task, i in zip(tasks.index, tasks["task_index"])}
        task_index = table["task_index"][chosen]
        unique = task_index.unique()
        tokens = instruction_tokens([text[int(i)] for i in unique])
        data["instruction"] = tokens[torch.searchsorted(unique, task_index)]
    if PHASE_KEY in columns:
        data["phase"] = table[PHASE_KEY].reshape(-1)[chosen]
    if config.skills is not None:  # the stage's skill as the policy's own input shows it: the task state's one-hot
        skill = table[TASK_STATE_KEY][chosen, : len(SKILLS)].argmax(-1)
        keep = torch.isin(skill, torch.tensor([SKILLS.index(s) for s in config.skills]))
        if not keep.any():
            raise ValueError(f"{root}'s selected episodes have no frame of {','.join(config.skills)}; "
                             f"choose skills the dataset acts")
        chosen = chosen[keep]
        data = {k: v[keep] for k, v in data.items()}
    if config.images and not config.blind:  # a blind control reads no frame: its cameras are blanked
        images = camera_frames(root, config.cameras, config.image_size)
        every = len(data["index"]) == ds.meta.total_frames and bool((data["index"] == torch.arange(len(data["index"]))).all())
        data.update({cam: images[cam] if every else images[cam][data["index"]] for cam in config.cameras})  # no copy
    if config.goal_keypoint_weight > 0:  # training labels only: where the goal is in each camera's image
        platform = get_platform((ds.meta.robot_type or "").removeprefix("aerobench_"))
        fields = task_state_fields(with_arm, version)
        data["goal_xy"], visible, depth = goal_pixels(table[STATE_KEY][chosen], table[TASK_STATE_KEY][chosen], fields,
                                                      platform, config.cameras)
        data["goal_visible"] = torch.stack([unoccluded(visible[:, c], data["goal_xy"][:, c], depth[:, c],
                                                       data[cam][:, 3], DEPTH_STEP_M)
                                            for c, cam in enumerate(config.cameras)], 1)
    facts = {"episodes": len(episodes), "frames": len(chosen), "robot_type": ds.meta.robot_type,
             "total_episodes": ds.meta.total_episodes, "total_frames": ds.meta.total_frames, "inputs": inputs.as_dict()}
    if config.objects is not None:
        facts["objects"] = list(config.objects)
    if config.skills is not None:
        facts["skills"] = list(config.skills)
    if config.aux_fields:
        facts["aux_fields"] = list(config.aux_fields)
    if config.goal_keypoint_weight > 0:  # how many frames carry a label, per camera
        facts["goal_in_view"] = dict(zip(config.cameras, data["goal_visible"].float().mean(0).round(decimals=3).tolist()))
    return data, facts


def segment_starts(segment: torch.Tensor) -> torch.Tensor:
    """The row of each row's segment's first frame (segments are contiguous, in order)."""
    t = torch.arange(len(segment))
    new = torch.ones(len(segment), dtype=torch.bool)
    new[1:] = segment[1:] != segment[:-1]
    return torch.cummax(torch.where(new, t, torch.zeros_like(t)), 0).values


def stage_segments(episode_index: torch.Tensor, stage: torch.Tensor | None) -> torch.Tensor:
    """A segment id per frame, new wherever the episode or its chain stage changes: a chained evaluation resets a
    stage's policy (and its input history) when the stage begins, so history frames never cross a stage boundary.
    Without a stage column (datasets exported before the annotation columns): one segment per episode."""
    new = torch.ones(len(episode_index), dtype=torch.bool)
    new[1:] = episode_index[1:] != episode_index[:-1]
    if stage is not None:
        stage = stage.reshape(-1)
        new[1:] |= stage[1:] != stage[:-1]
    return torch.cumsum(new, 0)


def demo_starts(config: BCConfig) -> TrainingStarts:
    """The starts of every episode of the dataset (all outcomes: the safe side for the held-out check)."""
    return dataset_starts(Path(config.dataset), source=config.dataset)


def switches(values: torch.Tensor, segment: torch.Tensor) -> torch.Tensor:
    """True on the frames whose value differs from the frame before it in the same segment (an episode's stage)."""
    switch = torch.zeros(len(values), dtype=torch.bool)
    switch[1:] = (values[1:] != values[:-1]) & (segment[1:] == segment[:-1])
    return switch


def gripper_targets(action: torch.Tensor, segment: torch.Tensor, onset_weight: float) -> tuple[torch.Tensor, torch.Tensor]:
    """The close label (1: close) of every frame and its weight: `onset_weight` on the frames where the command
    switches within a segment (an episode's stage), 1 elsewhere."""
    close = is_close(action[:, -1])
    return close, torch.where(switches(close, segment), torch.full_like(close, onset_weight), torch.ones_like(close))


def phase_onset_weights(phase: torch.Tensor, segment: torch.Tensor, frames: int, weight: float) -> torch.Tensor:
    """`weight` on the `frames` frames from each switch of the expert's phase within a segment, 1 elsewhere: the
    frames where the expert decides (align -> descend), a few among many of near-identical inputs it holds on."""
    switch = switches(phase, segment)
    recent = switch.clone()
    for k in range(1, frames):
        recent[k:] |= switch[:-k] & (segment[k:] == segment[:-k])
    return torch.where(recent, torch.full((len(phase),), weight), torch.ones(len(phase)))


def goal_keypoint_error(keypoints: dict[str, torch.Tensor], goal_xy: torch.Tensor, visible: torch.Tensor,
                        offsets: list[torch.Tensor], pad: int, size: int) -> torch.Tensor:
    """The mean squared distance between each camera's first keypoint and the goal's position in its (shifted) image,
    over the frames where the goal is in view (0 when it is in none)."""
    errors, count = [], 0
    for c, kp in enumerate(keypoints.values()):  # in the cameras' order, as the offsets
        k = kp.shape[1] // 2
        target = shifted(goal_xy[:, c], offsets[c], pad, size)
        seen = visible[:, c]
        errors.append(((kp[:, [0, k]] - target).pow(2).sum(-1) * seen).sum())
        count += int(seen.sum())
    return torch.stack(errors).sum() / max(count, 1)


def flight_mse(pred: torch.Tensor, target: torch.Tensor, weight: torch.Tensor | None) -> torch.Tensor:
    """The MSE of the continuous action dimensions, frames weighted by `weight` (None: the plain mean)."""
    if weight is None:
        return F.mse_loss(pred, target)
    return (weight * (pred - target).pow(2).mean(-1)).sum() / weight.sum()


# ── training ──────────────────────────────────────────────────────────────────────────────────────────────────────


def train_bc(config: BCConfig) -> Path:
    """Train (or resume) a BC policy; returns the checkpoint folder (`--policy bc --checkpoint DIR`)."""
    with torch_threads(config.threads):
        return _train_bc(config)


def _train_bc(config: BCConfig) -> Path:
    out = Path(config.out)
    current = config_dict(config)
    start, train_state = 0, None
    checkpoint = recover_checkpoint(out)
    if checkpoint is not None:
        saved = read_config(checkpoint)
        if saved["algorithm"] != "bc":
            raise ValueError(f"{out} holds a {saved['algorithm']} run; choose another --out")
        check_resumable(saved["train"], current, out, RESUMABLE_CHANGES)
        train_state = load_train_state(checkpoint, out)
        start = train_state["step"]
        if start >= config.steps:
            return checkpoint

    data, facts = load_demos(config)
    state_dim, action_dim = data["state"].shape[1], data["action"].shape[1]
    cameras = config.cameras if config.images and not config.blind else ()  # the images the network is given
    inputs = InputSpec.from_dict(facts["inputs"])
    model = config.model(inputs, state_dim, action_dim)
    normalizer = Normalizer(normalization_stats(data["state"], data["action"], config.gripper))
    targets = normalizer.action(data["action"])
    states = normalizer.state(data["state"])
    close, close_weight = gripper_targets(data["action"], data["segment"], config.onset_weight)
    flight_weight = None if config.phase_onset_weight == 1 else \
        phase_onset_weights(data["phase"], data["segment"], config.history, config.phase_onset_weight)
    binary = config.gripper == "binary"
    if config.aux_fields:  # auxiliary targets, standardized like the actions
        aux_mean, aux_std = data["aux"].mean(0), data["aux"].std(0, unbiased=False).clamp_min(STD_FLOOR)
        aux_targets = (data["aux"] - aux_mean) / aux_std
    # the head's targets in their own units, for whatever reads the head (`policies.perceive_act`)
    aux_scale = {"aux_mean": aux_mean.tolist(), "aux_std": aux_std.tolist()} if config.aux_fields else {}

    noisy = None if not config.goal_noise_m else goal_noise(config.goal_noise_m, inputs, data["state"].shape[1])
    seed_everything(config.seed)
    actor = make_actor(model)
    optimizer = torch.optim.Adam(actor.parameters(), lr=config.learning_rate)
    if train_state is not None:
        actor.load_state_dict({k.removeprefix("actor."): v for k, v in load_weights(checkpoint).items()})
        optimizer.load_state_dict(train_state["optimizer"])

    if config.close_threshold != 0.5:  # a setting of the acting policy, not of its training (older checkpoints: none)
        model = {**model, "close_threshold": config.close_threshold}
    meta = {"algorithm": "bc", "model": model, "train": current, "data": facts, "inputs_tier": model_tier(model),
            "platform": facts["robot_type"].removeprefix("aerobench_") if facts["robot_type"] else None}

    starts = demo_starts(config)

    def save(step: int) -> Path:
        weights = {f"actor.{k}": v for k, v in actor.state_dict().items()}
        state = {"step": step, "optimizer": optimizer.state_dict()}
        return save_checkpoint(out, meta, weights, {**normalizer.as_dict(), **aux_scale}, state, starts)

    log = ScalarLog(out, start)
    bar = _progress(config, start)
    n = len(states)
    t0, steps_done, loss_sum, aux_sum, kp_sum = time.perf_counter(), 0, 0.0, 0.0, 0.0
    path = checkpoint
    actor.train()
    for step in range(start + 1, config.steps + 1):
        generator = torch.Generator().manual_seed(config.seed * BATCH_SEED_STRIDE + step)
        idx = torch.randint(n, (min(config.batch_size, n),), generator=generator)
        keypoints = {} if config.goal_keypoint_weight > 0 else None
        offsets = [] if keypoints is not None else None  # each camera's shift, for the goal keypoint labels
        batch = {"state": states[idx] if noisy is None else normalizer.state(data["state"][idx] + noisy(idx)), **{cam: random_shift(as_network_input(data[cam][idx]), config.shift, generator,
                                                            offsets) for cam in cameras}}
        if inputs.instruction:
            batch["instruction"] = data["instruction"][idx]
        features = actor.embed(batch, keypoints)
        pred = actor.mlp(features)
        frame_weight = None if flight_weight is None else flight_weight[idx]
        if binary:  # MSE on the continuous dimensions, weighted cross-entropy on close
            w = close_weight[idx]
            bce = F.binary_cross_entropy_with_logits(pred[:, -1], close[idx], reduction="none")
            loss = flight_mse(pred[:, :-1], targets[idx, :-1], frame_weight) + config.gripper_weight * (w * bce).sum() / w.sum()
        else:
            loss = flight_mse(pred, targets[idx], frame_weight)
        if config.aux_fields:
            aux_error = actor.aux(features) - aux_targets[idx]
            loss = loss + config.aux_weight * aux_error.pow(2).mean()
            aux_sum += (aux_error.detach() * aux_std).pow(2).mean(0)  # squared error in the fields' own units
        if keypoints is not None:
            kp_error = goal_keypoint_error(keypoints, data["goal_xy"][idx], data["goal_visible"][idx], offsets,
                                           config.shift, config.image_size)
            loss = loss + config.goal_keypoint_weight * kp_error
            kp_sum += kp_error.item()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        loss_sum += loss.item()
        steps_done += 1
        if step % config.log_every == 0 or step == config.steps:
            elapsed = time.perf_counter() - t0
            log.add("losses/bc", loss_sum / steps_done, step)
            log.add("charts/SPS", steps_done / elapsed, step)  # gradient steps per second
            log.add("charts/frames_per_s", steps_done * len(idx) / elapsed, step)
            if config.aux_fields:  # how well the inputs tell the targets, e.g. the goal's offset in metres
                log.add("losses/aux_rmse", float((aux_sum / steps_done).mean().sqrt()), step)
            if keypoints is not None:  # mean squared image-position error of the goal keypoints (image: -1 to 1)
                log.add("losses/goal_keypoint", kp_sum / steps_done, step)
            if bar is not None:
                bar.set_postfix_str(f"loss {loss_sum / steps_done:.4f}")
            t0, steps_done, loss_sum, aux_sum, kp_sum = time.perf_counter(), 0, 0.0, 0.0, 0.0
        if step % config.save_every == 0 or step == config.steps:
            log.flush()  # the scalars up to a checkpoint are on disk before it
            path = save(step)
        if bar is not None:
            bar.update(1)
    log.close()
    if bar is not None:
        bar.close()
    return path


def _progress(config: BCConfig, start: int):
    if not config.progress:
        return None
    from tqdm import tqdm

    return tqdm(total=config.steps, initial=start, unit="step", desc="bc", dynamic_ncols=True)
