"""Batched geometry against scene boxes: distances, the drone's collision proxy, start-pose feasibility.

Scenes are unions of oriented boxes (`scenes.layout.Box`), so clearances and collision-free checks are analytic and
need no simulator query. Packed boxes are a tensor `(N, B, 8)`: centre xyz, half sizes xyz, yaw, valid flag, one row
of B boxes per env (padded with invalid rows where envs have fewer boxes).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from .platforms import PlatformSpec
from .scenes.layout import Box

FAR_M = 1e3  # distance reported for padding boxes


def pack_boxes(per_env: Sequence[Sequence[Box]], device: torch.device | str = "cpu") -> torch.Tensor:
    """`(N, B, 8)` tensor of the boxes of each env (B = the largest count; missing rows have valid = 0)."""
    width = max((len(b) for b in per_env), default=0)
    packed = torch.zeros(len(per_env), max(width, 1), 8)
    for i, boxes in enumerate(per_env):
        for j, b in enumerate(boxes):
            packed[i, j] = torch.tensor([*b.center, *b.half_size, b.yaw, 1.0])
    return packed.to(device)


def _box_fields(boxes: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """The packed boxes `(N, B, 8)` field by field, each `(N, 1, B)` (a row of boxes, broadcast over points): centre
    xyz, half sizes xyz, valid flag, and the yaw's cosine and sine. One field-first table, built by one `cat`: a
    compiled kernel then takes each box's cosine and sine once and walks the boxes with contiguous loads, instead of
    taking them again for every point with a stride of 8 (about 10x faster for the airframe's 43 points against a
    hundred boxes, docs/performance.md)."""
    yaw = boxes[..., 6]
    table = torch.cat([boxes.transpose(1, 2), torch.cos(yaw)[:, None], torch.sin(yaw)[:, None]], 1)[:, :, None, :]
    return tuple(table[:, i] for i in (0, 1, 2, 3, 4, 5, 7, 8, 9))


def point_box_distance(points: torch.Tensor, boxes: torch.Tensor) -> torch.Tensor:
    """Signed distance from points `(N, P, 3)` to boxes `(N, B, 8)`: `(N, P, B)`, negative inside.

    Exact for boxes rotated about z: transform the point into the box frame and take the box SDF.
    """
    cx, cy, cz, hx, hy, hz, valid, c, s = _box_fields(boxes)
    # per axis, not as (..., 3) stacks: a reduction over a trailing axis of 3 costs a CPU several times an
    # elementwise op, and this runs every control step (the airframe's clearance)
    dx, dy, dz = points[..., 0, None] - cx, points[..., 1, None] - cy, points[..., 2, None] - cz
    qx = (c * dx + s * dy).abs() - hx
    qy = (c * dy - s * dx).abs() - hy
    qz = dz.abs() - hz
    ox, oy, oz = qx.clamp_min(0.0), qy.clamp_min(0.0), qz.clamp_min(0.0)
    dist = (ox * ox + oy * oy + oz * oz).sqrt() + torch.maximum(torch.maximum(qx, qy), qz).clamp_max(0.0)
    return torch.where(valid > 0.5, dist, FAR_M)


def min_distance_to_boxes(points: torch.Tensor, boxes: torch.Tensor) -> torch.Tensor:
    """Smallest signed distance of any point to any box, `(N,)` (over boxes, then points: nested loops in a compiled
    kernel, where one reduction over the flattened pairs divides an index at every pair)."""
    return point_box_distance(points, boxes).amin(dim=-1).amin(dim=-1)


def drone_proxy_points_body(platform: PlatformSpec, rim_samples: int = 8) -> tuple[torch.Tensor, float]:
    """Points on the drone's rigid geometry (rotor-disk rims, frame, manipulator mount) in the body frame.

    Returns `(P, 3)` points and the radius to subtract (the disks' half thickness plus a small margin), so that
    "distance minus radius" is a conservative clearance of the airframe. Fingers are left out on purpose (the
    spec's clearance check C excludes them; grasp contacts are intended).
    """
    r = platform.rotors
    pts = []
    for x, y in r.positions_xy:
        for k in range(rim_samples):
            a = 2 * math.pi * k / rim_samples
            pts.append((x + r.disk_radius_m * math.cos(a), y + r.disk_radius_m * math.sin(a), r.height_m))
        pts.append((x, y, r.height_m))
    pts += [(0.0, 0.0, 0.0), (0.07, 0.07, -0.02), (0.07, -0.07, -0.02), (-0.07, 0.07, -0.02), (-0.07, -0.07, -0.02)]
    if platform.arm is None:
        gp = platform.grasp_point_m
        pts += [(0.0, 0.0, -0.10), (0.0, 0.0, gp[2] + 0.12)]  # gripper mast and palm
    return torch.tensor(pts, dtype=torch.float32), r.disk_thickness_m / 2 + 0.01


def body_points_to_world(points_body: torch.Tensor, position: torch.Tensor, rotation: torch.Tensor) -> torch.Tensor:
    """`(P, 3)` body points -> `(N, P, 3)` world points for poses `(N, 3)`, `(N, 3, 3)`."""
    return position[:, None, :] + torch.einsum("nij,pj->npi", rotation, points_body)


def level_drone_points(positions: torch.Tensor, yaw: torch.Tensor, points_body: torch.Tensor) -> torch.Tensor:
    """Proxy points of a level drone at candidate positions `(N, K, 3)` and headings `(N, K)`: `(N, K, P, 3)`."""
    c, s = torch.cos(yaw)[..., None], torch.sin(yaw)[..., None]
    px, py, pz = points_body[:, 0], points_body[:, 1], points_body[:, 2]
    return torch.stack(
        [positions[..., 0:1] + c * px - s * py, positions[..., 1:2] + s * px + c * py, positions[..., 2:3] + pz], dim=-1
    )


def level_airframe_room(
    grasp_points: torch.Tensor, headings: torch.Tensor, grasp_body: torch.Tensor, boxes: torch.Tensor,
    points_body: torch.Tensor, radius: float,
) -> torch.Tensor:
    """The clearance `(N, K)` a level airframe keeps from `boxes` `(N, B, 8)` when its grasp point stands at
    `grasp_points` `(N, K, 3)` with heading `headings` `(N, K)`; `grasp_body` `(N, 3)` is the grasp point in the body
    frame (the arm's pose), `points_body` / `radius` the airframe's proxy points (`drone_proxy_points_body`)."""
    c, s = torch.cos(headings), torch.sin(headings)
    gx, gy, gz = grasp_body[:, None, 0], grasp_body[:, None, 1], grasp_body[:, None, 2]
    centres = grasp_points - torch.stack([c * gx - s * gy, s * gx + c * gy, gz.expand_as(c)], -1)
    points = level_drone_points(centres, headings, points_body)  # (N, K, P, 3)
    n, k, p = points.shape[:3]
    room = point_box_distance(points.reshape(n, k * p, 3), boxes).amin(-1).reshape(n, k, p).amin(-1)
    return room - radius


def boxes_near(points: torch.Tensor, boxes: torch.Tensor, reach_m: float) -> torch.Tensor:
    """The boxes `(N, B', 8)` of `boxes` that may come within `reach_m` of any of `points` `(N, Q, 3)` in some env;
    for the others "distance > reach" holds for every point (signed distance is 1-Lipschitz: a box further than
    reach + r from the points' centroid, r their largest distance from it, is further than reach from each). A
    column selection with a host synchronization: for start sampling, not the per-step path."""
    centre = points.mean(dim=1, keepdim=True)  # (N, 1, 3)
    spread = torch.linalg.norm(points - centre, dim=-1).max(dim=1).values  # (N,)
    from_centre = point_box_distance(centre, boxes)[:, 0]  # (N, B)
    return boxes[:, (from_centre <= spread[:, None] + reach_m).any(dim=0)]


def points_clear_of_boxes(points: torch.Tensor, boxes: torch.Tensor, clearance_m: float) -> torch.Tensor:
    """Which points `(N, Q, 3)` are more than `clearance_m` from every box: `(N, Q)`. Only the boxes that can come that
    near are measured (`boxes_near`: the candidates of a start stand around one anchor, most of a house is far)."""
    near = boxes_near(points, boxes, clearance_m)
    if near.shape[1] == 0:
        return torch.ones(points.shape[:2], dtype=torch.bool, device=points.device)
    return point_box_distance(points, near).amin(dim=-1) > clearance_m


def is_pose_free(
    positions: torch.Tensor, yaw: torch.Tensor, boxes: torch.Tensor, points_body: torch.Tensor, clearance_m: float
) -> torch.Tensor:
    """Which candidate level poses `(N, K)` keep every proxy point `clearance_m` away from every box."""
    n, k = positions.shape[:2]
    pts = level_drone_points(positions, yaw, points_body).reshape(n, -1, 3)
    return points_clear_of_boxes(pts, boxes, clearance_m).reshape(n, k, -1).all(dim=-1)


VIEW_POINT_CANDIDATES = 12  # directions around the target tried at each distance


def free_view_point(target: torch.Tensor, boxes: torch.Tensor, lo: torch.Tensor, hi: torch.Tensor) -> torch.Tensor:
    """`(M, 3)` a point 0.9 m above and 2.2, 1.6 or 1.1 m beside each `target` `(M, 3)` (the farthest that works) that
    lies inside the workspace `lo`..`hi` `(M, 3)` and more than 0.1 m from every box (`boxes`, `pack_boxes` layout),
    the one with the most clearance; where none does, 1.6 m behind and 0.9 m above (a third-person camera's eye)."""
    m, device = len(target), target.device
    angles = torch.linspace(0, 2 * math.pi, VIEW_POINT_CANDIDATES + 1, device=device)[:-1]
    best_eye = target + torch.tensor([-1.6, 0.0, 0.9], device=device)
    best_score = torch.full((m,), -1e9, device=device)
    for dist in (2.2, 1.6, 1.1):
        eye = target[:, None] + torch.stack(
            [dist * torch.cos(angles), dist * torch.sin(angles), torch.full_like(angles, 0.9)], -1
        )[None]
        eye[..., 2] = torch.minimum(eye[..., 2], hi[:, None, 2] - 0.15)
        clearance = point_box_distance(eye, boxes).min(-1).values
        inside = ((eye > lo[:, None] + 0.05) & (eye < hi[:, None] - 0.05)).all(-1)
        score = torch.where(inside & (clearance > 0.1), clearance + dist, torch.full_like(clearance, -1e9))
        k = score.argmax(-1)
        top = score[torch.arange(m), k]
        better = top > best_score
        best_eye = torch.where(better[:, None], eye[torch.arange(m), k], best_eye)
        best_score = torch.maximum(best_score, top)
    return best_eye
