"""Batched geometry against scene boxes: the box cull of start sampling changes no answer."""

import math

import numpy as np
import pytest
import torch

from aerobench.envs.geometry import (
    boxes_near,
    drone_proxy_points_body,
    is_pose_free,
    level_drone_points,
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
