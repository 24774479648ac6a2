"""Where the active skill's goal point is in each onboard camera's image: a training-time label for the camera CNN.

A camera policy that cannot say where the object is cannot fly to it (docs/experiments.md, "Why Pick fails": the
auxiliary head's estimate of the grasp point errs by 0.27 m at 0.3-1 m). The simulator knows where the goal is, and
the cameras are fixed to the airframe, so the goal's image position in every frame follows from what a dataset
already records: the airframe pose (proprio state) and the goal relative to the tool centre point (task state). A
keypoint of the camera CNN (`--encoder-head keypoints`) is then trained to sit on it (`aerobench train bc
--goal-keypoint-weight`), as keypoint supervision does in pose estimation; the policy never reads the label, so its
input tier is unchanged.

The goal point per skill (task state `goal_pos`, docs of `envs.observations`): Pick, Open, Close: the TCP plus
`goal_pos` (the planned grasp point); Place: the object's bottom centre plus `goal_pos` (the marked placement goal);
Nav: the airframe centre plus `goal_pos`. Image coordinates follow `SpatialSoftmax`: x right, y down, -1 and +1 at
the image's edges. A point behind a camera or outside its view is not visible (occlusion is not modelled).
"""

from __future__ import annotations

import torch

from ..envs.observations import STATE_FIELDS, field_slices
from ..envs.platforms import PlatformSpec
from ..envs.tasks import SKILLS
from ..policies.camera_input import camera_frames_in_body
from ..policies.egocentric import body_rotation

_STATE = field_slices(STATE_FIELDS)
# The goal point lies inside its object (a grasp point) or under it (a place goal under the held object): a surface
# up to this much nearer than the point at its pixel is the object itself, not an occluder.
OCCLUSION_MARGIN_M = 0.15


def goal_point_world(state: torch.Tensor, task_state: torch.Tensor, task_fields, tcp_body: tuple[float, ...]
                     ) -> tuple[torch.Tensor, torch.Tensor]:
    """The active skill's goal point in the env frame `(N, 3)`, and the airframe's rotation `(N, 3, 3)` (body to
    env), from the proprio `state` `(N, 19+)` and the task state `(N, K)` in the layout `task_fields`."""
    state, task_state = state.double(), task_state.double()
    fields = field_slices(task_fields)
    rotation = body_rotation(state)
    centre = state[:, _STATE["position"]]
    tcp = centre + rotation @ torch.tensor(tcp_body, dtype=torch.float64)
    goal = task_state[:, fields["goal_pos"]]
    skill = task_state[:, fields["skill"]].argmax(-1)
    origin = torch.where((skill == SKILLS.index("nav"))[:, None], centre, tcp)
    place = (skill == SKILLS.index("place"))[:, None]
    origin = torch.where(place, tcp + task_state[:, fields["tcp_to_obj_pos"]], origin)
    return origin + goal, rotation


def goal_pixels(state: torch.Tensor, task_state: torch.Tensor, task_fields, platform: PlatformSpec,
                cameras: tuple[str, ...]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The goal point's image position in each camera `(N, C, 2)` (x right, y down, in [-1, 1] inside the image),
    whether it is in view `(N, C)` (in front of the camera and inside the image) and its depth along each camera's
    axis `(N, C)` (m, as the depth images measure it)."""
    goal, rotation = goal_point_world(state, task_state, task_fields, platform.grasp_point_m)
    eye, axes, tan_half = camera_frames_in_body(platform, cameras)
    body = ((goal - state[:, _STATE["position"]].double())[:, None, :] @ rotation).squeeze(1)  # goal in body frame
    in_camera = torch.einsum("ncj,cjk->nck", body[:, None, :] - eye[None], axes)  # forward, left, up
    depth = in_camera[..., 0]
    safe = depth.clamp_min(1e-6)
    xy = torch.stack([-in_camera[..., 1] / safe, -in_camera[..., 2] / safe], -1) / tan_half[None, :, None]
    visible = (depth > 1e-3) & (xy.abs() <= 1.0).all(-1)
    return torch.where(visible[..., None], xy, 0.0).float(), visible, depth.float()  # no label out of view


def unoccluded(visible: torch.Tensor, xy: torch.Tensor, depth: torch.Tensor, depth_levels: torch.Tensor,
               step_m: float, margin_m: float = OCCLUSION_MARGIN_M) -> torch.Tensor:
    """`visible` `(N,)` less the frames where the depth image `(N, s, s)` (levels of `step_m`; 0: no return) sees
    something more than `margin_m` in front of the goal point at its pixel: the palm over an object in the hand
    camera, a distractor in front of it."""
    size = depth_levels.shape[-1]
    pixel = ((xy + 1) / 2 * size).long().clamp(0, size - 1)
    level = depth_levels[torch.arange(len(xy)), pixel[:, 1], pixel[:, 0]].float()
    return visible & ((level == 0) | (level * step_m >= depth - margin_m))


def shifted(xy: torch.Tensor, offsets: torch.Tensor, pad: int, size: int) -> torch.Tensor:
    """Image positions `(N, 2)` after `random_shift` moved an image of `size` pixels by `offsets` `(N, 2)` (its
    drawn x and y crop origins in the padded image): content at pixel u lands at u - (offset - pad)."""
    return xy - 2.0 * (offsets.to(xy.dtype) - pad) / size
