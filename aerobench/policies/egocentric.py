"""What a policy can compute from its own proprioception, in its own heading frame (the `vision` tier's numbers).

A camera policy sees the scene from the airframe, but the env's action is a world-frame velocity (`[u_x, u_y, u_z,
u_psi, ...]`, envs.platforms) and the proprioceptive state gives world-frame position and velocity. A network
that reads pixels would have to learn the rotation between the two frames from data. These features and the action
frame do it exactly instead, from `observation.state` alone (so they stay in the `vision` tier, `aerobench.tiers`):

| field | size | meaning |
| --- | --- | --- |
| velocity_heading | 3 | airframe velocity in the heading frame (x forward, y left, z up), m/s |
| angular_velocity_body | 3 | rad/s, body frame (the state's own) |
| gravity_body_xy | 2 | x and y of the unit gravity direction in the body frame (roll and pitch) |
| height | 1 | the airframe centre's height, m (the state's z: the scenes' floors are at 0) |
| yaw_since_start | 2 | sin and cos of the yaw turned since the episode's (or chain stage's) first frame |
| finger_position / finger_velocity | 2 / 2 | the state's own |
| arm_position / arm_velocity | 3 / 3 | the state's own (arm platform) |

Absolute x and y are left out: they are positions in one procedural layout and say nothing about the next.
With `action_frame = "heading"` a policy predicts `u_x, u_y` in the heading frame (forward, left) and they are
turned into the world frame with the current yaw before the env gets them (`to_world_frame`); training turns the
demonstrations' world-frame commands the other way (`to_heading_frame`).
"""

from __future__ import annotations

import torch

from ..envs.observations import ARM_STATE_FIELDS, STATE_FIELDS, field_slices, heading_frame

EGO_FIELDS = (
    ("velocity_heading", 3),
    ("angular_velocity_body", 3),
    ("gravity_body_xy", 2),
    ("height", 1),
    ("yaw_since_start", 2),
    ("finger_position", 2),
    ("finger_velocity", 2),
    ("arm_position", 3),
    ("arm_velocity", 3),
)
EGO_FIELD_NAMES = tuple(name for name, _ in EGO_FIELDS)
ACTION_FRAMES = ("world", "heading")
_STATE = field_slices(STATE_FIELDS + ARM_STATE_FIELDS)


def yaw_of(state: torch.Tensor) -> torch.Tensor:
    """`(..., )` yaw of proprio states `(..., S)`: the heading of the body x axis (R's first column)."""
    r = state[..., _STATE["orientation_6d"]]
    return torch.atan2(r[..., 1], r[..., 0])


def body_rotation(state: torch.Tensor) -> torch.Tensor:
    """`(..., 3, 3)` the airframe's rotation (body to env frame) of proprio states `(..., S)`, from the state's two
    columns of R (`orientation_6d`)."""
    x_axis, y_axis = state[..., _STATE["orientation_6d"]].split(3, -1)
    return torch.stack([x_axis, y_axis, torch.linalg.cross(x_axis, y_axis)], -1)


def ego_features(state: torch.Tensor, start_state: torch.Tensor | None, names: tuple[str, ...]) -> torch.Tensor:
    """`(T, F)` the fields `names` (of `EGO_FIELDS`, in that order of `names`) from proprio states `(T, S)`;
    `start_state` `(T, S)`: each row's episode (or stage) start, needed by `yaw_since_start`."""
    state = state.float()
    yaw = yaw_of(state)
    parts = []
    for name in names:
        if name == "velocity_heading":
            parts.append(heading_frame(state[:, _STATE["linear_velocity"]], yaw))
        elif name == "gravity_body_xy":  # -R^T e_z: minus the z components of R's first two columns
            r = state[:, _STATE["orientation_6d"]]
            parts.append(-torch.stack([r[:, 2], r[:, 5]], -1))
        elif name == "height":
            parts.append(state[:, _STATE["position"]][:, 2:3])
        elif name == "yaw_since_start":
            if start_state is None:
                raise ValueError("yaw_since_start needs the episode's first state")
            turned = yaw - yaw_of(start_state.float())
            parts.append(torch.stack([torch.sin(turned), torch.cos(turned)], -1))
        elif name in _STATE:
            if _STATE[name].stop > state.shape[-1]:
                raise ValueError(f"the gripper platform's state has no {name}")
            parts.append(state[:, _STATE[name]])
        else:
            raise ValueError(f"unknown egocentric field {name!r}; valid: {', '.join(EGO_FIELD_NAMES)}")
    return torch.cat(parts, -1) if parts else state[:, :0]


def _turn_xy(action: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    c, s = torch.cos(angle), torch.sin(angle)
    x, y = action[:, 0], action[:, 1]
    return torch.cat([torch.stack([c * x - s * y, s * x + c * y], -1), action[:, 2:]], -1)


def to_heading_frame(action: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """World-frame actions `(T, A)` with `u_x, u_y` turned into the heading frame of `yaw` `(T,)`."""
    return _turn_xy(action, -yaw)


def to_world_frame(action: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """Heading-frame actions `(T, A)` turned back into the world frame (the env's)."""
    return _turn_xy(action, yaw)
