"""Batched geometry against scene boxes: the box cull of start sampling changes no answer."""

import math

import numpy as np
import pytest
import torch

from aerobench.envs.geometry import (
    boxes_near,
    drone_proxy_points_body,
    free_view_point,
    is_pose_free,
    level_drone_points,
    min_distance_to_boxes,
    pack_boxes,
    point_box_distance,
)
from aerobench.envs.platforms import ARM_PLATFORM, GRIPPER_PLATFORM
from aerobench.envs.scenes import generate_layout


@pytest.mark.parametrize("scene, platform", [("apartment", GRIPPER_PLATFORM), ("kitchen", ARM_PLATFORM), ("home", ARM_PLATFORM)])
def test_culled_start_check_is_the_brute_force_one(scene, platform):
    layout = generate_layout(scene, np.random.default_rng(7))
    boxes = pack_boxes([layout.boxes, layout.boxes[: len(layout.boxes) // 2]])  # two envs, the second padded
    points_body, _ = drone_proxy_points_body(platform)
    g = torch.Generator().manual_seed(0)
    lo, hi = torch.tensor(layout.workspace_lo), torch.tensor(layout.workspace_hi)
    anchors = lo + torch.rand(6, 2, 3, generator=g) * (hi - lo)  # 6 draws of one anchor per env
    some_free = some_blocked = 0
    for anchor in anchors:
        positions = anchor[:, None] + (torch.rand(2, 64, 3, generator=g) * 2 - 1) * 0.8  # candidates around it
        yaw = (torch.rand(2, 64, generator=g) * 2 - 1) * math.pi
        for clearance in (0.0, 0.05, 0.3):
            culled = is_pose_free(positions, yaw, boxes, points_body, clearance)
            pts = level_drone_points(positions, yaw, points_body)  # (2, 64, P, 3)
            brute = point_box_distance(pts.reshape(2, -1, 3), boxes).reshape(2, 64, -1).min(-1).values > clearance
            assert torch.equal(culled, brute)
            some_free += int(brute.sum())
            some_blocked += int((~brute).sum())
        assert boxes_near(pts.reshape(2, -1, 3), boxes, 0.05).shape[1] < boxes.shape[1]  # it does drop boxes
    assert some_free > 0 and some_blocked > 0  # both answers occur, so the equality means something


def test_point_box_distance_is_the_signed_distance():
    """Against the closest point of each box, found by clamping in the box frame (outside), and the nearest face
    (inside), for points in, near and far from boxes of any yaw; padding rows read as far away."""
    g = torch.Generator().manual_seed(3)
    n, p, b = 2, 40, 9
    boxes = torch.zeros(n, b, 8)
    boxes[..., 0:3] = torch.rand(n, b, 3, generator=g) * 2 - 1
    boxes[..., 3:6] = 0.05 + torch.rand(n, b, 3, generator=g) * 0.4
    boxes[..., 6] = (torch.rand(n, b, generator=g) * 2 - 1) * math.pi
    boxes[..., 7] = 1.0
    boxes[1, -2:, 7] = 0.0  # the second env has two padding rows
    points = torch.rand(n, p, 3, generator=g) * 3 - 1.5
    points[:, :b] = boxes[..., 0:3] + 0.5 * boxes[..., 3:6] * (torch.rand(n, b, 3, generator=g) * 2 - 1)  # inside

    got = point_box_distance(points, boxes).numpy()
    pts, bx = points.numpy().astype(np.float64), boxes.numpy().astype(np.float64)
    inside = 0
    for i in range(n):
        for j in range(b):
            if bx[i, j, 7] < 0.5:
                assert np.all(got[i, :, j] == 1e3)
                continue
            c, s = math.cos(bx[i, j, 6]), math.sin(bx[i, j, 6])
            to_box = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # world -> box frame
            local = (pts[i] - bx[i, j, :3]) @ to_box.T
            half = bx[i, j, 3:6]
            closest = np.clip(local, -half, half)
            outside = np.linalg.norm(local - closest, axis=-1)
            depth = (half - np.abs(local)).min(-1)  # to the nearest face, positive inside
            expected = np.where(outside > 0, outside, -depth)
            inside += int((outside == 0).sum())
            np.testing.assert_allclose(got[i, :, j], expected, atol=2e-6)
    assert inside >= n * b  # the inside branch is exercised
    assert torch.equal(min_distance_to_boxes(points, boxes), point_box_distance(points, boxes).flatten(1).amin(1))


def test_a_view_point_is_in_the_room_and_clear_of_the_furniture_or_the_default_behind():
    from aerobench.envs.scenes.layout import Box

    target = torch.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    wall = Box("wall", (3.0, 0.0, 1.5), (0.5, 5.0, 1.5))  # blocks every eye on the +x side
    boxes = pack_boxes([[wall], [wall]])
    lo = torch.tensor([[-5.0, -5.0, 0.0], [-0.1, -0.1, 0.0]])  # the second room leaves no candidate inside
    hi = torch.tensor([[5.0, 5.0, 3.0], [0.1, 0.1, 3.0]])
    eye = free_view_point(target, boxes, lo, hi)
    assert torch.all(eye[0] > lo[0]) and torch.all(eye[0] < hi[0])
    assert float(point_box_distance(eye[:1, None], boxes[:1]).min()) > 0.1
    assert torch.linalg.norm(eye[0, :2]) == pytest.approx(2.2, abs=1e-4)  # the farthest ring that fits
    assert torch.allclose(eye[1], torch.tensor([-1.6, 0.0, 1.9]))
