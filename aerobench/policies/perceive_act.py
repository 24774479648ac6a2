"""Perceive, then act: a camera network estimates the task-state fields a state controller was trained on, and the
controller acts on the estimates. A `vision`-tier policy: it reads the cameras, the proprioception and the
instruction; the task state only labelled the two networks' training (the perception's auxiliary head, the
controller's inputs), as "learning by cheating" trains a privileged agent and then what sees to stand in for it.

Why split it (docs/experiments.md, "What a camera Pick must know"): a BC that reads the privileged `goal_pos_body`,
`heading_error` and `is_grasp_confirmed` with the `vision` tier's proprioception picks most held-out starts, and
still about half when what it reads of the goal is off by 2 cm an episode; every end-to-end camera BC trained on the
same demonstrations picks none, although its auxiliary head estimates those fields. The split makes the controller's
use of the estimate explicit instead of leaving it to one network trained on actions.

A folder (`aerobench train perceive-act`) holds `config.json` (`PERCEIVE_ACT_FORMAT`: the fields, the auxiliary
head's target scale, which fields are flags), `perception/` (a `bc` checkpoint with an auxiliary head over the fields,
`aerobench train bc --aux-fields`) and `controller/` (a `bc` or `ppo` checkpoint whose task-state fields are all
among them). At each step the perception's head is run, flags are thresholded at 0.5, and the controller reads a task
state holding the estimates (zeros elsewhere: it reads no other field); the env's own task state is never read.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch

from .. import tiers
from ..envs.observations import STATE_FIELDS, field_slices, heading_frame, task_state_fields
from ..envs.tasks import object_phrase
from .camera_input import back_project, camera_frames_in_body, depth_at
from .egocentric import body_rotation, yaw_of
from .instruction import named_phrase
from .learned import BCPolicy, PPOPolicy, model_features, read_config, resolve_checkpoint
from .provenance import STARTS_FILE, TrainingStarts, read_starts
from .registry import register_policy

PERCEIVE_ACT_FORMAT = "aerobench-perceive-act-v1"
PERCEPTION, CONTROLLER = "perception", "controller"
FLAG_FIELDS = ("is_grasp_confirmed", "doorway_ahead")  # 0/1 in the task state: the estimate is thresholded
_STATE = field_slices(STATE_FIELDS)


def read_perceive_act(checkpoint: str | Path | None) -> tuple[Path, dict]:
    """The folder and its config; one-line errors for anything else."""
    if not checkpoint:
        raise ValueError("--policy perceive_act needs --checkpoint DIR (an `aerobench train perceive-act` folder)")
    path = Path(checkpoint).expanduser()
    try:
        config = json.loads((path / "config.json").read_text())
    except (OSError, json.JSONDecodeError):
        config = None
    if not isinstance(config, dict) or config.get("format") != PERCEIVE_ACT_FORMAT:
        raise ValueError(f"no perceive-act policy at {path}: make one with `aerobench train perceive-act "
                         f"--perception BC --controller BC --out {path}`")
    return path, config


def keypoint_goal_offset(images: torch.Tensor, keypoints: torch.Tensor, state: torch.Tensor, eye: torch.Tensor,
                         axes: torch.Tensor, tan_half: float, tcp_body: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Where a camera's first keypoint (trained onto the goal, `--goal-keypoint-weight`) and the depth image under it
    put the goal: `(N, 3)` its offset from the tool centre point in the heading frame (as `goal_pos_body`), and the
    depth read `(N,)` (0: no return). `images` `(N, 4, s, s)` network input, `keypoints` `(N, 2K)` the camera's, raw
    proprio `state` `(N, S)`, the camera's mount `eye`, `axes`, `tan_half` (`camera_frames_in_body`)."""
    k = keypoints.shape[1] // 2
    xy = torch.stack([keypoints[:, 0], keypoints[:, k]], -1)
    depth = depth_at(images, xy)
    offset = body_rotation(state) @ (back_project(xy, depth, eye, axes, tan_half) - tcp_body)[..., None]
    return heading_frame(offset[..., 0], yaw_of(state)), depth


class KeypointGoal:
    """The goal's horizontal offset from the cameras' goal keypoints where they see it, else the head's: within
    `near_m` of the goal (by the head) the `near` camera's (the hand camera, under the jaws); otherwise the first
    camera (`near`, then the `far` ones) that sees the goal. A keypoint of a camera that does not see the goal lands on
    whatever it does see, so "sees" is gated: by the keypoint's attention spread under `spread_max` (a concentrated
    map found its thing; `SpatialSoftmax`) and/or, for the far cameras, by the keypoint putting the goal within
    `gate_m` of the head's estimate (None: no such gate). The head is linear in features that hold image positions, so
    it cannot multiply them by depth; this does it exactly.

    The vertical offset, too, where the near camera sees the goal within `depth_z_range_m`: the depth under the
    keypoint is the top of the object, a fixed height above its grasp point per object (`depth_z`: object name ->
    grasp point minus keypoint surface (m), measured on demonstrations, `train.perceive_act.depth_z_offsets`; the
    object is the one the instruction names). At the grasp the head's vertical estimate errs about 4 cm RMS, this
    one under 1 cm (docs/experiments.md)."""

    def __init__(self, platform, near: str, far: tuple[str, ...] = (), near_m: float = 0.3,
                 gate_m: float | None = 0.2, spread_max: float | None = None, depth_z: dict[str, float] | None = None,
                 depth_z_range_m: float = 0.05, device: torch.device | str = "cpu"):
        self.near, self.far, self.near_m, self.gate_m, self.spread_max = near, tuple(far), near_m, gate_m, spread_max
        self.depth_z_names = [object_phrase(name) for name in depth_z] if depth_z else None
        self.depth_z = torch.tensor([*depth_z.values(), float("nan")], device=device) if depth_z else None
        self.depth_z_range_m = depth_z_range_m
        self.cameras = (near, *self.far)
        eye, axes, tan_half = camera_frames_in_body(platform, self.cameras)
        self.mounts = {c: (eye[i].float().to(device), axes[i].float().to(device), float(tan_half[i]))
                       for i, c in enumerate(self.cameras)}
        self.tcp_body = torch.tensor(platform.grasp_point_m, device=device)

    @classmethod
    def from_config(cls, platform, config: dict, device: torch.device | str = "cpu") -> KeypointGoal | None:
        """The fusion a composed folder's `config.json` names (None: no `keypoint_camera`, the head alone)."""
        if not config.get("keypoint_camera"):
            return None
        gate, spread = config.get("keypoint_gate_m", 0.2), config.get("keypoint_spread_max")
        return cls(platform, config["keypoint_camera"], tuple(config.get("far_keypoint_cameras") or ()),
                   float(config["keypoint_range_m"]), None if gate is None else float(gate),
                   None if spread is None else float(spread), config.get("depth_z"),
                   float(config.get("depth_z_range_m", 0.05)), device)

    def seen(self, camera: str, images: torch.Tensor, keypoints: torch.Tensor, state: torch.Tensor
             ) -> tuple[torch.Tensor, torch.Tensor]:
        return keypoint_goal_offset(images, keypoints, state, *self.mounts[camera], self.tcp_body)

    def _concentrated(self, camera: str, spreads: dict[str, torch.Tensor] | None, like: torch.Tensor) -> torch.Tensor:
        if self.spread_max is None:
            return torch.ones_like(like, dtype=torch.bool)
        if spreads is None:
            raise ValueError("a keypoint spread gate needs the encoders' spreads (Trunk.embed(..., spreads={}))")
        return spreads[camera][:, 0] < self.spread_max

    def fuse(self, head: torch.Tensor, images: dict[str, torch.Tensor], keypoints: dict[str, torch.Tensor],
             state: torch.Tensor, spreads: dict[str, torch.Tensor] | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """`(N, 3)` the goal's offset (as `goal_pos_body`) from the head's `(N, 3)` and the cameras, and `(N,)`
        whether a camera saw the goal (the horizontal offset is a keypoint's, not the head's). `images`: the
        network's inputs (the cameras, and the instruction's word ids where `depth_z` is used)."""
        offset, depth = self.seen(self.near, images[self.near], keypoints[self.near], state)
        near = head.norm(dim=-1) < self.near_m
        if self.spread_max is not None:  # farther too, where the near camera's keypoint is sure of itself
            near |= self._concentrated(self.near, spreads, depth)
        done = near & (depth > 0)
        out = torch.where(done[:, None], offset[:, :2], head[:, :2])
        z = head[:, 2]
        if self.depth_z is not None:
            if "instruction" not in images:
                raise ValueError("the vertical offset from depth needs the instruction (the object it names)")
            named = named_phrase(images["instruction"], self.depth_z_names)
            seen_z = offset[:, 2] + self.depth_z[named]  # index -1: NaN, no object named
            close = done & ~seen_z.isnan() & (torch.cat([out, seen_z[:, None]], -1).norm(dim=-1) < self.depth_z_range_m)
            z = torch.where(close, seen_z, z)
        for camera in self.far:
            offset, depth = self.seen(camera, images[camera], keypoints[camera], state)
            sees = ~done & (depth > 0) & self._concentrated(camera, spreads, depth)
            if self.gate_m is not None:
                sees &= (offset[:, :2] - head[:, :2]).norm(dim=-1) < self.gate_m
            out = torch.where(sees[:, None], offset[:, :2], out)
            done |= sees
        return torch.cat([out, z[:, None]], -1), done


class StaticGoalFilter:
    """An exponential average of the goal's estimates in the env frame, per episode: until the object is grasped the
    goal does not move, so frame-to-frame errors of the estimate are noise about a fixed point, not motion. `rate`:
    the weight of each new estimate (1: no filtering). As a goal memory, it is told which estimates are sightings
    (`KeypointGoal.fuse`): only they update it, and between them it holds the last one (dead reckoning by the
    airframe's own motion) instead of passing the head's estimate on. Uses the airframe's position and attitude from
    the proprio state (differences within an episode only); a grasped object (by the estimate) passes through and
    clears it."""

    def __init__(self, rate: float, tcp_body: torch.Tensor):
        if not 0.0 < rate <= 1.0:
            raise ValueError(f"the goal filter's rate must be in (0, 1], got {rate}")
        self.rate, self.tcp_body = rate, tcp_body
        self.goal: torch.Tensor | None = None  # (N, 3) the env-frame estimate
        self.known: torch.Tensor | None = None  # (N,) an estimate is held this episode

    def reset(self, env_idx: torch.Tensor) -> None:
        if self.known is not None:
            self.known[env_idx.to(self.known.device)] = False

    def __call__(self, offset: torch.Tensor, state: torch.Tensor, grasped: torch.Tensor,
                 sighted: torch.Tensor | None = None) -> torch.Tensor:
        """`(N, 3)` the filtered heading-frame offset (as `goal_pos_body`) from this step's estimate `offset`;
        `sighted` `(N,)`: which estimates update it (None: all)."""
        n = len(offset)
        if self.known is None or len(self.known) != n:
            self.known = torch.zeros(n, dtype=torch.bool, device=offset.device)
            self.goal = offset.new_zeros(n, 3)
        tcp = state[:, _STATE["position"]] + (body_rotation(state) @ self.tcp_body[:, None])[..., 0]
        yaw = yaw_of(state)
        world = tcp + heading_frame(offset, -yaw)  # the heading frame turned back by the yaw: the env frame
        update = ~grasped if sighted is None else sighted & ~grasped
        blended = torch.where(self.known[:, None], self.goal + self.rate * (world - self.goal), world)
        self.goal = torch.where(update[:, None], blended, self.goal)
        self.known = (self.known | update) & ~grasped  # after a grasp the next sighting starts afresh
        return torch.where(self.known[:, None], heading_frame(self.goal - tcp, yaw), offset)


class _EstimatedTaskState:
    """The env as the controller sees it: everything the env has, except that its task state is the estimate."""

    def __init__(self, env):
        self._env = env
        self.estimate: torch.Tensor | None = None

    def __getattr__(self, name):
        return getattr(self._env, name)

    def task_state(self) -> torch.Tensor:
        if self.estimate is None:
            raise RuntimeError("the controller acted before the perception estimated its inputs")
        return self.estimate


@register_policy("perceive_act")
class PerceiveActPolicy:
    """The controller acting on the perception's estimates of its task-state fields (see the module)."""

    algorithm = "perceive_act"

    def __init__(self, env, checkpoint: str | None = None, **_):
        self.name = self.algorithm
        path, config = read_perceive_act(checkpoint)
        self.fields = tuple(config["fields"])
        self.perception = BCPolicy(env, str(path / PERCEPTION))
        self.seen = _EstimatedTaskState(env)
        controller = path / CONTROLLER
        self.controller = (PPOPolicy if read_config(controller)["algorithm"] == "ppo" else BCPolicy)(self.seen,
                                                                                                   str(controller))
        device = self.perception.device
        self.mean = torch.tensor(config["aux_mean"], device=device)
        self.std = torch.tensor(config["aux_std"], device=device)
        layout = task_state_fields(with_arm=env.platform.arm is not None)
        slices = field_slices(layout)
        self.width = sum(n for _, n in layout)
        self.columns = torch.tensor([i for f in self.fields for i in range(slices[f].start, slices[f].stop)],
                                    device=device)
        sizes = dict(layout)
        self.flags = torch.tensor([f in FLAG_FIELDS for f in self.fields for _ in range(sizes[f])], device=device)
        self.goal_column = sum(sizes[f] for f in self.fields[:self.fields.index("goal_pos_body")]) \
            if "goal_pos_body" in self.fields else None
        # the goal's offset from the cameras' goal keypoints
        self.keypoints = KeypointGoal.from_config(env.platform, config, device)
        # a static-goal filter on goal_pos_body (`StaticGoalFilter`); as a memory, updated by the keypoints' sightings
        self.memory = bool(config.get("goal_memory")) and self.keypoints is not None
        rate = config.get("goal_filter_rate")
        rate = 1.0 if rate is None and self.memory else rate
        self.filter = None if rate is None or "goal_pos_body" not in self.fields else StaticGoalFilter(
            float(rate), torch.tensor(env.platform.grasp_point_m, device=device))
        self.grasp_column = sum(sizes[f] for f in self.fields[:self.fields.index("is_grasp_confirmed")]) \
            if "is_grasp_confirmed" in self.fields else None

    @classmethod
    def _parts(cls, checkpoint: str | None) -> tuple[Path, Path]:
        path, _ = read_perceive_act(checkpoint)
        return resolve_checkpoint(path / PERCEPTION), resolve_checkpoint(path / CONTROLLER)

    @classmethod
    def needs_images(cls, checkpoint: str | None) -> bool:
        return BCPolicy.needs_images(str(cls._parts(checkpoint)[0]))

    @classmethod
    def input_features(cls, checkpoint: str | None) -> list[str]:
        """What the two networks read from the env: the perception's inputs and the controller's, less the task state
        (the controller reads the perception's estimate of it)."""
        perception, controller = cls._parts(checkpoint)
        read = model_features(read_config(perception)["model"]) + [
            f for f in model_features(read_config(controller)["model"]) if f != tiers.ENVIRONMENT_STATE]
        return list(dict.fromkeys(read))

    @classmethod
    def input_tier(cls, checkpoint: str | None) -> str:
        return tiers.tier_of(cls.input_features(checkpoint))

    @classmethod
    def training_starts(cls, checkpoint: str) -> TrainingStarts:
        """The starts either network trained on, and those of the demonstrations its calibration was measured on."""
        perception, controller = cls._parts(checkpoint)
        starts = read_starts(perception)
        starts.add(read_starts(controller))
        folder = read_perceive_act(checkpoint)[0]
        if (folder / STARTS_FILE).is_file():
            starts.add(read_starts(folder))
        return starts

    def reset(self, env_idx: torch.Tensor) -> None:
        self.perception.reset(env_idx)
        self.controller.reset(env_idx)
        if self.filter is not None:
            self.filter.reset(env_idx)

    @torch.no_grad()
    def estimate(self, obs) -> torch.Tensor:
        """`(N, K)` the task state the controller reads: the perception's estimates of `fields`, zeros elsewhere."""
        actor = self.perception.actor
        inputs, keypoints = self.perception.observe(obs), {}
        spreads = {} if self.keypoints is not None and self.keypoints.spread_max is not None else None
        values = actor.aux(actor.embed(inputs, keypoints if self.keypoints else None, spreads)) * self.std + self.mean
        values = torch.where(self.flags, (values > 0.5).to(values.dtype), values)  # a new tensor: written below
        state = obs["agent"]["state"].to(values.device).float()
        goal = slice(self.goal_column, self.goal_column + 3) if self.goal_column is not None else None
        sighted = None
        if self.keypoints is not None:
            values[:, goal], sighted = self.keypoints.fuse(values[:, goal], inputs, keypoints, state, spreads)
        if self.filter is not None:
            grasped = values[:, self.grasp_column] > 0.5 if self.grasp_column is not None else \
                torch.zeros(len(values), dtype=torch.bool, device=values.device)
            values[:, goal] = self.filter(values[:, goal], state, grasped, sighted if self.memory else None)
        out = values.new_zeros(len(values), self.width)
        out[:, self.columns] = values
        return out

    @torch.no_grad()
    def act(self, obs) -> torch.Tensor:
        self.seen.estimate = self.estimate(obs)
        return self.controller.act(obs)
