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

The privileged task state (`TASK_STATE_FIELDS`, 13 values; `AeroSkillEnv.task_state()`, exported as LeRobot's
`observation.environment_state`) is what state-based skill policies (BC, PPO) see besides the proprio state, as
ManiSkill's state observations do; camera-based policies need not use it. All positions in the env frame:

| index | field | notes |
| --- | --- | --- |
| 0-2 | tool centre point position | m |
| 3-5 | target object position | m; zeros in envs without an object (nav, open, close) |
| 6-9 | target object orientation, quaternion wxyz | (1, 0, 0, 0) without an object |
| 10-12 | the active skill's goal point | pick: the planned grasp point; place: the placement goal; nav: the target; open / close: the handle |
"""

from __future__ import annotations

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
TASK_STATE_FIELDS = (("tcp_position", 3), ("object_position", 3), ("object_quaternion_wxyz", 4), ("goal_position", 3))
TASK_STATE_DIM = sum(n for _, n in TASK_STATE_FIELDS)
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
    parts = [airframe.position, R[:, :, 0], R[:, :, 1], airframe.velocity, airframe.angular_velocity_body, finger_q, finger_qd]
    if arm_q is not None and arm_q.shape[-1] > 0:
        parts += [arm_q, arm_qd]
    return torch.cat(parts, dim=-1).float()


def _names(fields) -> list[str]:
    return [f"{field}.{i}" for field, n in fields for i in range(n)]


def state_field_names(with_arm: bool) -> list[str]:
    """One name per state dimension, e.g. for LeRobot feature `names`."""
    return _names(STATE_FIELDS + (ARM_STATE_FIELDS if with_arm else ()))


def task_state_field_names() -> list[str]:
    return _names(TASK_STATE_FIELDS)
