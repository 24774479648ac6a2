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


def state_field_names(with_arm: bool) -> list[str]:
    """One name per state dimension, e.g. for LeRobot feature `names`."""
    names = []
    for field, n in STATE_FIELDS + (ARM_STATE_FIELDS if with_arm else ()):
        names += [f"{field}.{i}" for i in range(n)]
    return names
