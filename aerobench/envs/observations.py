"""The proprioceptive state policies see, documented once.

Spec appendix "Observation Space": a 19-dimensional proprioceptive state with gripper states, UAV position and
orientation, and linear and angular velocities. Layout (`STATE_FIELDS`, in this order):

| index | field | unit / frame |
| --- | --- | --- |
| 0-2 | position of the airframe centre | m, env frame |
| 3-8 | orientation: first two columns of R (body x and body y axes in the env frame), the continuous 6-D form | - |
| 9-11 | linear velocity of the airframe centre | m/s, env frame |
| 12-14 | angular velocity | rad/s, body frame |
| 15-16 | finger positions (left, right): half-opening each, 0 closed to 0.055 open | m |
| 17-18 | finger velocities | m/s |

The arm platform appends its three arm joint positions and velocities (shoulder, elbow, wrist): 25 values.
Cameras (`drone_front`, `drone_hand`, `drone_own`, RGB-D 128x128) and the language instruction come separately.

The task state (`TASK_STATE_FIELDS`, 31 values; `AeroSkillEnv.task_state()`, exported as LeRobot's
`observation.environment_state`) is what state-based policies (BC, PPO, the state-only ACT / Diffusion variants)
read, as ManiSkill's state observations do: the active skill's geometry as *relative* vectors (so a policy learns
"fly towards the grasp point", not the absolute start positions of its training episodes), the heading error the
skill needs, and the flight state. It holds no finger position or velocity: a policy that sees its own fingers
narrowing copies "fingers closing -> keep closing and lift" from the demonstrations instead of deciding when to close
(docs/experiments.md, "Why BC learned nothing"). It is the same layout for every skill; camera policies need not
use it. Positions in metres, in the env (world) frame unless the name says body:

| index | field | meaning |
| --- | --- | --- |
| 0-4 | skill | one-hot of the active skill: pick, place, nav, open, close |
| 5-7 | goal_pos | the active goal minus the point it is for: pick: planned grasp point - TCP; place: placement goal - object bottom centre; nav: target - airframe centre; open / close: handle grasp point - TCP |
| 8-10 | goal_pos_body | the same vector in the heading frame (x forward, y left, z up) |
| 11-13 | tcp_to_obj_pos | object bottom centre - TCP (zeros without an object) |
| 14 | heading_error | rad, the skill's goal heading minus the yaw, wrapped to the goal's symmetry: pick: the grasp heading planned at the skill's start (mod pi for boxes, pi/2 for round objects); place, nav: the heading at the skill's start; open / close: facing the handle |
| 15 | progress | pick: the object's lift above its resting height (m); place: seconds the goal support has carried the object without a break, capped at 1 s (the expert releases at 0.45 s); open / close: articulation progress q_bar; nav: 0 |
| 16 | is_grasp_confirmed | 1 once both fingers have pinched the target (open / close: the handle, since version 5) for `GRASP_CONFIRM_STEPS` control steps in a row, else 0 (a tactile signal, delayed so that it reports a grasp, not a closing command); an episode that starts with the object in the jaws (Place) starts confirmed |
| 17-19 | linear_velocity | airframe velocity, m/s |
| 20-22 | angular_velocity_body | rad/s, body frame |
| 23-24 | gravity_body_xy | x and y of the unit gravity direction in the body frame (roll and pitch) |
| 25 | altitude | airframe height above the floor |
| 26 | grasp_side_room | half of (the open gripper's width - the target object's width across its grasp): the room each finger leaves beside the object, which sets how exactly a grasp must be aligned (master chef can 4 mm, sugar box 36 mm); 0 without an object (version 3) |
| 27 | doorway_ahead | 1 while the active goal is in another room than the airframe centre (PackageDelivery's Place from the street, a transport between rooms), else 0 (version 4) |
| 28-30 | doorway_pos | the centre of the first doorway on the room route to the goal (mid-wall, 1.5 m up) - airframe centre; zeros when `doorway_ahead` is 0 (`scenes.room_routes`: the scene's rooms and openings, not the expert's planned path) (version 4) |

The arm platform appends its three arm joint positions (`arm_position`, rad): 34 values.

Older task states (`task_state_fields(with_arm, version)`): versions 1 and 2 have neither `grasp_side_room` nor the
doorway (26 values, 29 with the arm), version 3 no doorway (27, 30). A policy reads its fields by name from whichever
layout a vector has (its width tells which), so a checkpoint trained on an older dataset acts in today's env
unchanged (`task_state_in_layout`).
"""

from __future__ import annotations

import functools

import torch

from .control.virtual_joints import AirframeState

STATE_FIELDS = (
    ("position", 3),
    ("orientation_6d", 6),
    ("linear_velocity", 3),
    ("angular_velocity_body", 3),
    ("finger_position", 2),
    ("finger_velocity", 2),
)
ARM_STATE_FIELDS = (("arm_position", 3), ("arm_velocity", 3))
TASK_STATE_FIELDS = (
    ("skill", 5),
    ("goal_pos", 3),
    ("goal_pos_body", 3),
    ("tcp_to_obj_pos", 3),
    ("heading_error", 1),
    ("progress", 1),
    ("is_grasp_confirmed", 1),
    ("linear_velocity", 3),
    ("angular_velocity_body", 3),
    ("gravity_body_xy", 2),
    ("altitude", 1),
    ("grasp_side_room", 1),
    ("doorway_ahead", 1),
    ("doorway_pos", 3),
)
TASK_STATE_DIM = sum(n for _, n in TASK_STATE_FIELDS)
assert TASK_STATE_DIM == 31
# Version of the task state's meaning, saved with every state policy. 1: Place `progress` was always 0. 2: it is the
# set-down time (the place expert releases on it). A version-1 checkpoint is fed Place progress 0 (policies.inputs).
# 3: `grasp_side_room` added (the pick expert's alignment before descending depends on it; docs/experiments.md).
# 4: `doorway_ahead`, `doorway_pos` added (a goal in another room: where the opening is; docs/experiments.md).
# 5: `is_grasp_confirmed` reports the handle's pinch in Open / Close (always 0 there before; docs/experiments.md).
TASK_STATE_VERSION = 5
FIELD_SINCE_VERSION = {"grasp_side_room": 3, "doorway_ahead": 4, "doorway_pos": 4}  # fields an older layout lacks
GRASP_CONFIRM_STEPS = 3  # control steps of a continuous pinch before `is_grasp_confirmed` reads 1
STATE_DIM = sum(n for _, n in STATE_FIELDS)
assert STATE_DIM == 19


def proprio_state(
    airframe: AirframeState,
    finger_q: torch.Tensor,
    finger_qd: torch.Tensor,
    arm_q: torch.Tensor | None = None,
    arm_qd: torch.Tensor | None = None,
) -> torch.Tensor:
    """`(N, 19)` (or `(N, 25)` with the arm) in the layout above."""
    R = airframe.rotation
    orientation_6d = R[:, :, :2].transpose(1, 2).reshape(R.shape[0], 6)  # R's first column, then its second
    parts = [airframe.position, orientation_6d, airframe.velocity, airframe.angular_velocity_body, finger_q, finger_qd]
    if arm_q is not None and arm_q.shape[-1] > 0:
        parts += [arm_q, arm_qd]
    return torch.cat(parts, dim=-1).float()


def _names(fields) -> list[str]:
    return [f"{field}.{i}" for field, n in fields for i in range(n)]


def state_field_names(with_arm: bool) -> list[str]:
    """One name per state dimension, e.g. for LeRobot feature `names`."""
    return _names(STATE_FIELDS + (ARM_STATE_FIELDS if with_arm else ()))


def task_state_fields(with_arm: bool, version: int = TASK_STATE_VERSION) -> tuple:
    """The task state's `(field, size)` layout in `version` (today's by default)."""
    fields = tuple(f for f in TASK_STATE_FIELDS if FIELD_SINCE_VERSION.get(f[0], 1) <= version)
    return fields + ((("arm_position", 3),) if with_arm else ())


def task_state_field_names(with_arm: bool = False, version: int = TASK_STATE_VERSION) -> list[str]:
    return _names(task_state_fields(with_arm, version))


def task_state_layout(width: int, with_arm: bool) -> tuple:
    """The layout of a task state vector `width` values wide: today's or an older version's (a dataset or a
    checkpoint made before a field was added)."""
    for version in range(TASK_STATE_VERSION, 0, -1):
        fields = task_state_fields(with_arm, version)
        if sum(n for _, n in fields) == width:
            return fields
    raise ValueError(f"a task state of {width} values is no layout of this aerobench's "
                     f"({TASK_STATE_DIM + 3 * with_arm} today); re-export the dataset with aerobench generate")


@functools.lru_cache(maxsize=16)
def _layout_columns(have_width: int, with_arm: bool, width: int) -> tuple[int, ...]:
    """The columns of a task state `have_width` wide that make up the layout `width` wide (looked up once)."""
    have, want = field_slices(task_state_layout(have_width, with_arm)), task_state_layout(width, with_arm)
    missing = [name for name, _ in want if name not in have]
    if missing:
        raise ValueError(f"this task state has no {missing}; the policy needs a newer aerobench")
    return tuple(i for name, _ in want for i in range(have[name].start, have[name].stop))


def task_state_in_layout(task_state: torch.Tensor, with_arm: bool, width: int) -> torch.Tensor:
    """`task_state` (`(..., K)`, any version's layout) in the layout `width` values wide: the fields that layout has,
    by name (a LeRobot policy trained on an older dataset reads the width its dataset had; called every step)."""
    if task_state.shape[-1] == width:
        return task_state
    columns = _layout_columns(task_state.shape[-1], with_arm, width)
    return task_state[..., torch.tensor(columns, device=task_state.device)]


def field_slices(fields) -> dict[str, slice]:
    """`{field: slice}` of a layout (`STATE_FIELDS`, `TASK_STATE_FIELDS`, ...): where each field sits in the vector."""
    out, start = {}, 0
    for name, n in fields:
        out[name] = slice(start, start + n)
        start += n
    return out


def wrap_angle(angle: torch.Tensor) -> torch.Tensor:
    """`angle` wrapped into [-pi, pi]."""
    return torch.atan2(torch.sin(angle), torch.cos(angle))


def wrap_to_period(angle: torch.Tensor, period: torch.Tensor | float) -> torch.Tensor:
    """`angle` wrapped into [-period/2, period/2): the error to the nearest of the headings `period` apart."""
    period = torch.as_tensor(period, dtype=angle.dtype, device=angle.device)
    return torch.remainder(angle + period / 2, period) - period / 2


def heading_frame(vectors: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """World vectors `(N, 3)` in the heading frame of yaw `(N,)` (x forward, y left, z up)."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    x, y = vectors[:, 0], vectors[:, 1]
    return torch.stack([c * x + s * y, -s * x + c * y, vectors[:, 2]], dim=-1)
