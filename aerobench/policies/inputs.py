"""What aerobench's learned policies (bc, ppo) read: named fields of the proprio state, of what the policy computes
from it in its own heading frame (`egocentric`), and of the task state; whether they read the instruction; in which
frame they act; and how many recent frames. A processor in LeRobot's sense: it sits between the observation and the
network and is saved with the checkpoint, so training and acting select exactly the same values.

Field names are those of `envs.observations` (`STATE_FIELDS`, `TASK_STATE_FIELDS`; the arm platform adds
`arm_position` / `arm_velocity`) and `egocentric.EGO_FIELDS`. The default reads the whole task state and nothing of
the proprio state: the task state already carries the flight state, and the proprio state's finger position and
velocity are what a policy copies instead of deciding when to close (docs/experiments.md). A `vision`-tier policy
(`aerobench.tiers`) reads no task state field.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass

import torch

from .. import tiers
from ..envs.observations import (
    ARM_STATE_FIELDS,
    STATE_FIELDS,
    TASK_STATE_VERSION,
    field_slices,
    task_state_fields,
    task_state_layout,
)
from ..envs.tasks import SKILLS
from .egocentric import ACTION_FRAMES, EGO_FIELD_NAMES, ego_features

ALL_TASK_FIELDS = tuple(name for name, _ in task_state_fields(with_arm=True))
TASK_SLICES = field_slices(task_state_fields(with_arm=False))  # the arm's fields come after these: same indices
ALL_STATE_FIELDS = tuple(name for name, _ in STATE_FIELDS + ARM_STATE_FIELDS)
FINGER_FIELDS = ("finger_position", "finger_velocity")


@dataclass(frozen=True)
class InputSpec:
    """`state_fields` of the proprio state, `ego_fields` computed from it (`egocentric`) and `task_fields` of the task
    state, in that order, per frame; `history` frames (the current one first, then older ones; an episode's first
    frame repeats until there are enough); `task_state_version`: the meaning of the task state the policy was trained
    on (`observations.TASK_STATE_VERSION`); `instruction`: whether the policy reads the language instruction;
    `action_frame`: "world" (the env's) or "heading" (`egocentric.to_world_frame` turns it for the env)."""

    state_fields: tuple[str, ...] = ()
    task_fields: tuple[str, ...] = ALL_TASK_FIELDS
    history: int = 1
    task_state_version: int = TASK_STATE_VERSION
    ego_fields: tuple[str, ...] = ()
    instruction: bool = False
    action_frame: str = "world"

    def __post_init__(self):
        object.__setattr__(self, "state_fields", tuple(self.state_fields))
        object.__setattr__(self, "task_fields", tuple(self.task_fields))
        object.__setattr__(self, "ego_fields", tuple(self.ego_fields))
        bad = [f for f in self.ego_fields if f not in EGO_FIELD_NAMES]
        if bad:
            raise ValueError(f"unknown egocentric fields {bad}; valid: {', '.join(EGO_FIELD_NAMES)}")
        if self.action_frame not in ACTION_FRAMES:
            raise ValueError(f"--action-frame must be one of {', '.join(ACTION_FRAMES)}, got {self.action_frame!r}")
        bad = [f for f in self.state_fields if f not in ALL_STATE_FIELDS]
        if bad:
            raise ValueError(f"unknown proprio state fields {bad}; valid: {', '.join(ALL_STATE_FIELDS)}")
        bad = [f for f in self.task_fields if f not in ALL_TASK_FIELDS]
        if bad:
            raise ValueError(f"unknown task state fields {bad}; valid: {', '.join(ALL_TASK_FIELDS)}")
        if not self.state_fields and not self.task_fields and not self.ego_fields:
            raise ValueError("a learned policy must read at least one proprio, egocentric or task state field")
        if not (isinstance(self.history, int) and self.history >= 1):
            raise ValueError(f"--history must be a positive integer, got {self.history}")
        if not 1 <= self.task_state_version <= TASK_STATE_VERSION:
            raise ValueError(f"task state version {self.task_state_version} is newer than this aerobench's "
                             f"({TASK_STATE_VERSION}); upgrade aerobench to use this checkpoint")

    @property
    def reads_task_state(self) -> bool:
        return bool(self.task_fields)

    @property
    def needs_start(self) -> bool:
        """Whether a frame needs its episode's first state (`yaw_since_start`)."""
        return "yaw_since_start" in self.ego_fields

    def features(self) -> list[str]:
        """The LeRobot feature keys these inputs read (cameras apart: the model names them), for `aerobench.tiers`."""
        out = [tiers.STATE] if self.state_fields or self.ego_fields else []
        out += [tiers.ENVIRONMENT_STATE] if self.task_fields else []
        return out + ([tiers.INSTRUCTION] if self.instruction else [])

    @functools.lru_cache(maxsize=8)  # noqa: B019 - a few frozen specs per process; read once per control step
    def _indices(self, with_arm: bool, task_width: int | None) -> tuple[torch.Tensor, torch.Tensor]:
        """Where the fields sit: in the proprio state of the platform and in the task state layout `task_width` values
        wide (today's, or an older version's: the fields are found by name)."""
        state = field_slices(STATE_FIELDS + (ARM_STATE_FIELDS if with_arm else ()))
        layout = task_state_layout(task_width, with_arm) if task_width is not None else task_state_fields(with_arm)
        task = field_slices(layout)
        missing = [f for f in self.state_fields if f not in state] + [f for f in self.task_fields if f not in task]
        if missing:
            where = "" if layout == task_state_fields(with_arm) else " in this older task state layout"
            raise ValueError(f"the {'arm' if with_arm else 'gripper'} platform's observations have no {missing}{where}")

        def gather(slices: dict[str, slice], names: tuple[str, ...]) -> torch.Tensor:
            return torch.tensor([i for n in names for i in range(slices[n].start, slices[n].stop)], dtype=torch.long)

        return gather(state, self.state_fields), gather(task, self.task_fields)

    def frame(self, state: torch.Tensor, task_state: torch.Tensor | None,
              start_state: torch.Tensor | None = None) -> torch.Tensor:
        """One frame's inputs `(T, F)` from proprio states `(T, S)`, task states `(T, K)` (the platform follows from
        the proprio size) and, for `yaw_since_start`, each row's episode (or stage) first state `(T, S)`."""
        with_arm = state.shape[-1] > sum(n for _, n in STATE_FIELDS)
        si, ti = (i.to(state.device) for i in self._indices(with_arm, task_state.shape[-1] if task_state is not None else None))
        parts = [state.float()[..., si]]
        if self.ego_fields:
            parts.append(ego_features(state, start_state, self.ego_fields))
        if self.task_fields:
            if task_state is None:
                raise ValueError("this policy reads the task state (observation.environment_state) but none was given")
            parts.append(self._as_trained(task_state.float().to(state.device))[..., ti])
        return torch.cat(parts, dim=-1)

    def _as_trained(self, task_state: torch.Tensor) -> torch.Tensor:
        """The task state in the meaning the policy was trained on: version 1 read Place `progress` as 0, versions
        1-4 read Open / Close `is_grasp_confirmed` as 0."""
        legacy_progress = self.task_state_version < 2 and "progress" in self.task_fields
        legacy_handle = self.task_state_version < 5 and "is_grasp_confirmed" in self.task_fields
        if not (legacy_progress or legacy_handle):
            return task_state
        skill = TASK_SLICES["skill"].start
        legacy = task_state.clone()
        if legacy_progress:
            place = task_state[..., skill + SKILLS.index("place")] > 0.5
            progress = TASK_SLICES["progress"].start
            legacy[..., progress] = legacy[..., progress].masked_fill(place, 0.0)
        if legacy_handle:
            handle = (task_state[..., skill + SKILLS.index("open")] > 0.5) | (task_state[..., skill + SKILLS.index("close")] > 0.5)
            confirmed = TASK_SLICES["is_grasp_confirmed"].start
            legacy[..., confirmed] = legacy[..., confirmed].masked_fill(handle, 0.0)
        return legacy

    def stack_episodes(self, frames: torch.Tensor, episode_index: torch.Tensor) -> torch.Tensor:
        """`(T, F)` frames of whole episodes in order -> `(T, history * F)`: each row with its `history - 1`
        predecessors of the same episode (the episode's first frame repeated before its start)."""
        if self.history == 1:
            return frames
        t = torch.arange(len(frames))
        new_episode = torch.ones(len(frames), dtype=torch.bool)
        new_episode[1:] = episode_index[1:] != episode_index[:-1]
        first = torch.cummax(torch.where(new_episode, t, torch.zeros_like(t)), 0).values  # each row's episode start
        return torch.cat([frames[torch.maximum(t - k, first)] for k in range(self.history)], dim=-1)

    def task_columns(self, name: str, width: int) -> torch.Tensor:
        """The columns of task field `name` in every frame of a `width`-wide input (`history` frames, the task fields
        last in each)."""
        sizes = dict(task_state_fields(with_arm=True))  # a field's size is the same on either platform
        if name not in self.task_fields:
            raise ValueError(f"this policy does not read {name}")
        frame = width // self.history
        start = frame - sum(sizes[f] for f in self.task_fields) + \
            sum(sizes[f] for f in self.task_fields[:self.task_fields.index(name)])
        return torch.tensor([k * frame + start + i for k in range(self.history) for i in range(sizes[name])])

    def as_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> InputSpec:
        return cls(**{"task_state_version": 1, **d})  # saved before the version was recorded: version 1


class FrameHistory:
    """The last `history` input frames of each env while acting (`(N, history * F)`), cleared per env on reset."""

    def __init__(self, history: int):
        self.history, self.frames, self.fresh = history, None, None

    def reset(self, env_idx: torch.Tensor) -> None:
        if self.fresh is not None:
            self.fresh[env_idx.to(self.fresh.device)] = True

    def push(self, frame: torch.Tensor) -> torch.Tensor:
        """Add the current frame `(N, F)` and return the stacked inputs `(N, history * F)`."""
        if self.history == 1:
            return frame
        self.frames = self._stacked(frame)
        self.fresh[:] = False
        return torch.cat(list(self.frames), dim=-1)

    def peek(self, frame: torch.Tensor) -> torch.Tensor:
        """The stacked inputs with `frame` as the current one, without keeping it (e.g. a value bootstrap)."""
        return frame if self.history == 1 else torch.cat(list(self._stacked(frame)), dim=-1)

    def _stacked(self, frame: torch.Tensor) -> torch.Tensor:
        if self.frames is None or self.frames.shape[1] != frame.shape[0]:
            self.frames = frame[None].repeat(self.history, 1, 1)
            self.fresh = torch.zeros(frame.shape[0], dtype=torch.bool, device=frame.device)
        fresh = self.fresh[None, :, None]
        return torch.where(fresh, frame[None].expand_as(self.frames), torch.cat([frame[None], self.frames[:-1]]))
