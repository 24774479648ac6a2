"""The cameras as aerobench's learned policies see them: per camera a uint8 `(N, 4, s, s)` image, RGB and depth.

The env renders 128x128 RGB (uint8) and depth (int16 millimetres). A policy reduces both to `s` pixels a side
(area average for RGB; nearest for depth, so that a "no return" zero does not blur into the depths beside it) and
quantizes depth to `DEPTH_STEP_M` (2 cm) levels, 0-5.1 m. Training reads the same uint8 images from the dataset
(`train.camera_frames`, with the same functions), so a network sees exactly the numbers at training and at acting.
The network gets them as floats in [0, 1] (`as_network_input`), with random shifts while it trains
(`random_shift`, as DrQ's image augmentation).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import torch
from torch.nn import functional as F

DEPTH_STEP_M = 0.02  # one depth level: 255 levels cover 0-5.1 m (indoor scenes); farther reads 255
IMAGE_CHANNELS = 4  # RGB + depth
UINT8_MAX = 255

if TYPE_CHECKING:
    from ..envs.platforms import PlatformSpec


def reduce_rgb(rgb: torch.Tensor, size: int) -> torch.Tensor:
    """uint8 `(N, 3, H, W)` -> uint8 `(N, 3, size, size)` (area average)."""
    if rgb.shape[-1] == size:
        return rgb.to(torch.uint8)
    return F.interpolate(rgb.float(), size=(size, size), mode="area").round().clamp(0, UINT8_MAX).to(torch.uint8)


def reduce_depth(depth_mm: torch.Tensor, size: int) -> torch.Tensor:
    """Millimetres `(N, H, W)` -> uint8 `(N, 1, size, size)` in `DEPTH_STEP_M` levels (nearest)."""
    d = depth_mm.float().clamp_min(0)[:, None]
    if d.shape[-1] != size:
        d = F.interpolate(d, size=(size, size), mode="nearest")
    return (d / (1000.0 * DEPTH_STEP_M)).round().clamp(0, UINT8_MAX).to(torch.uint8)


def camera_images(obs: dict, cameras: tuple[str, ...], size: int) -> dict[str, torch.Tensor]:
    """Per camera, the policy's uint8 `(N, 4, size, size)` image from an aerobench env observation (on its device)."""
    out = {}
    for cam in cameras:
        data = obs["sensor_data"][cam]
        rgb = reduce_rgb(data["rgb"].permute(0, 3, 1, 2), size)
        out[cam] = torch.cat([rgb, reduce_depth(data["depth"][..., 0], size)], 1)
    return out


def as_network_input(images: torch.Tensor) -> torch.Tensor:
    """uint8 `(N, 4, s, s)` -> float in [0, 1] (depth: 1 = 5.1 m)."""
    return images.float() / UINT8_MAX


def random_shift(images: torch.Tensor, pad: int, generator: torch.Generator,
                 offsets_out: list | None = None) -> torch.Tensor:
    """Each image `(N, C, s, s)` shifted by up to `pad` pixels in x and y (edges repeated): the same scene seen from a
    slightly different place, so the network does not key on exact pixel positions (DrQ, Kostrikov et al. 2020).
    `offsets_out`, if given, receives the drawn crop origins `(N, 2)` (x, y; `pad` is no shift), so a label that
    names an image position can move with its image (`train.goal_pixels.shifted`)."""
    n, c, h, w = images.shape
    if pad == 0:
        if offsets_out is not None:
            offsets_out.append(torch.zeros(n, 2, dtype=torch.long))
        return images
    padded = F.pad(images, (pad, pad, pad, pad), mode="replicate")
    dy = torch.randint(0, 2 * pad + 1, (n,), generator=generator).to(images.device)
    dx = torch.randint(0, 2 * pad + 1, (n,), generator=generator).to(images.device)
    if offsets_out is not None:
        offsets_out.append(torch.stack([dx, dy], -1).cpu())
    rows = (dy[:, None] + torch.arange(h, device=images.device))[:, None, :, None].expand(n, c, h, w + 2 * pad)
    cropped = padded.gather(2, rows)
    cols = (dx[:, None] + torch.arange(w, device=images.device))[:, None, None, :].expand(n, c, h, w)
    return cropped.gather(3, cols)


def camera_frames_in_body(platform: PlatformSpec, cameras: tuple[str, ...]) -> tuple[torch.Tensor, torch.Tensor,
                                                                                          torch.Tensor]:
    """Per camera: its eye `(C, 3)` and axes `(C, 3, 3)` (columns: forward, left, up, SAPIEN's camera frame) in the
    airframe's body frame, and `tan(fov / 2)` `(C,)`. Cameras on another link than the airframe (the arm's wrist
    camera) move with the joints and are refused."""
    from mani_skill.utils import sapien_utils

    mounts = {c.uid: c for c in platform.cameras}
    unknown = [c for c in cameras if c not in mounts]
    if unknown:
        raise ValueError(f"the {platform.name} platform has no camera {', '.join(unknown)}")
    moving = [c for c in cameras if mounts[c].link != "airframe"]
    if moving:
        raise ValueError(f"goal keypoints need cameras fixed to the airframe; {', '.join(moving)} rides on a joint "
                         f"(train with --cameras naming airframe cameras, or without --goal-keypoint-weight)")
    poses = [sapien_utils.look_at(mounts[c].eye_m, mounts[c].target_m).to_transformation_matrix()[0] for c in cameras]
    eye = torch.stack([p[:3, 3] for p in poses]).double()
    axes = torch.stack([p[:3, :3] for p in poses]).double()
    tan_half = torch.tensor([math.tan(mounts[c].fov_rad / 2) for c in cameras], dtype=torch.float64)
    return eye, axes, tan_half


def back_project(xy: torch.Tensor, depth_m: torch.Tensor, eye: torch.Tensor, axes: torch.Tensor,
                 tan_half: torch.Tensor) -> torch.Tensor:
    """The point in the body frame `(N, 3)` seen at image position `xy` `(N, 2)` (x right, y down, -1 and +1 at the
    image's edges) at `depth_m` `(N,)` along the axis of a camera at `eye` `(3,)` with `axes` `(3, 3)` and
    `tan_half` (`camera_frames_in_body`): the inverse of projecting a point into the image (`train.goal_pixels`)."""
    scale = depth_m * tan_half
    in_camera = torch.stack([depth_m, -xy[:, 0] * scale, -xy[:, 1] * scale], -1)  # forward, left, up
    return eye + in_camera @ axes.T


def depth_at(images: torch.Tensor, xy: torch.Tensor) -> torch.Tensor:
    """`(N,)` metres: the depth channel of network-input images `(N, 4, s, s)` (`as_network_input`) at image
    positions `xy` `(N, 2)`, nearest pixel (0: no return)."""
    size = images.shape[-1]
    pixel = ((xy + 1) / 2 * size).long().clamp(0, size - 1)
    level = images[torch.arange(len(xy), device=images.device), IMAGE_CHANNELS - 1, pixel[:, 1], pixel[:, 0]]
    return level * UINT8_MAX * DEPTH_STEP_M
