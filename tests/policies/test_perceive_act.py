"""`perceive_act` (`policies.perceive_act`): a camera network's estimates stand in for the task state a state
controller reads. Near the goal the goal's offset comes from a camera keypoint and the depth under it, the exact
inverse of how the keypoint's label was projected (`train.goal_pixels`)."""

import math

import torch

from aerobench.envs.observations import heading_frame, task_state_fields
from aerobench.envs.platforms import get_platform
from aerobench.policies.camera_input import DEPTH_STEP_M, IMAGE_CHANNELS, UINT8_MAX
from aerobench.policies.perceive_act import KeypointGoal, StaticGoalFilter
from aerobench.train.goal_pixels import goal_pixels

FIELDS = task_state_fields(False)


def _pick_states(n: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """Tilted airframes at random headings above a grasp point 0.05-0.25 m below the TCP (a Pick's final approach)."""
    state, task = torch.zeros(n, 19), torch.zeros(n, sum(k for _, k in FIELDS))
    yaw = torch.rand(n, generator=generator) * 2 * math.pi
    roll, pitch = (torch.rand(2, n, generator=generator) - 0.5) * 0.2
    cy, sy, cp, sp, cr, sr = yaw.cos(), yaw.sin(), pitch.cos(), pitch.sin(), roll.cos(), roll.sin()
    rotation = torch.stack([  # Rz(yaw) Ry(pitch) Rx(roll): body -> env
        torch.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
        torch.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
        torch.stack([-sp, cp * sr, cp * cr], -1)], -2)
    state[:, 0:3] = torch.tensor([1.0, 2.0, 1.2])
    state[:, 3:6], state[:, 6:9] = rotation[:, :, 0], rotation[:, :, 1]
    task[:, 0] = 1.0  # pick
    goal = torch.stack([(torch.rand(n, generator=generator) - 0.5) * 0.08, (torch.rand(n, generator=generator) - 0.5)
                        * 0.08, -0.05 - 0.2 * torch.rand(n, generator=generator)], -1)  # heading frame
    task[:, 8:11] = goal
    world = torch.stack([cy * goal[:, 0] - sy * goal[:, 1], sy * goal[:, 0] + cy * goal[:, 1], goal[:, 2]], -1)
    task[:, 5:8] = world
    return state, task


def test_the_keypoint_and_its_depth_give_back_the_goal_offset_the_label_was_projected_from():
    platform = get_platform("gripper")
    state, task = _pick_states(64, torch.Generator().manual_seed(0))
    xy, visible, depth = goal_pixels(state, task, FIELDS, platform, ("drone_hand",))
    assert visible.all()
    fusion = KeypointGoal(platform, "drone_hand", near_m=0.3)
    keypoints = torch.zeros(64, 8)
    keypoints[:, 0], keypoints[:, 4] = xy[:, 0, 0], xy[:, 0, 1]  # the first keypoint's x and y
    images = torch.zeros(64, IMAGE_CHANNELS, 64, 64)
    images[:, -1] = (depth[:, 0] / (UINT8_MAX * DEPTH_STEP_M))[:, None, None]  # a flat depth image at the goal's depth
    head = task[:, 8:11] + torch.tensor([0.05, -0.04, 0.0])  # a head 6 cm off
    fused = fusion.fuse(head, {"drone_hand": images}, {"drone_hand": keypoints}, state)
    # the keypoint sits in one of the image's 64 pixels: about 4 mm at these ranges
    assert (fused - task[:, 8:10]).abs().max() < 6e-3
    far = head + torch.tensor([0.5, 0.0, 0.0])  # the head puts the goal beyond the near camera's range: its estimate
    assert torch.equal(fusion.fuse(far, {"drone_hand": images}, {"drone_hand": keypoints}, state), far[:, :2])


def test_a_far_camera_is_believed_only_where_it_agrees_with_the_head():
    platform = get_platform("gripper")
    state, task = _pick_states(8, torch.Generator().manual_seed(1))
    fusion = KeypointGoal(platform, "drone_hand", far=("drone_own",), near_m=0.3, gate_m=0.2)
    goal = torch.tensor([0.6, 0.1, -0.3]).expand(8, 3)  # ahead and below, in the downward-forward camera's view
    task = task.clone()
    task[:, 8:11] = goal
    yaw = torch.atan2(state[:, 4], state[:, 3])  # the heading of the body x axis
    cy, sy = yaw.cos(), yaw.sin()
    task[:, 5:8] = torch.stack([cy * goal[:, 0] - sy * goal[:, 1], sy * goal[:, 0] + cy * goal[:, 1], goal[:, 2]], -1)
    xy, visible, depth = goal_pixels(state, task, FIELDS, platform, ("drone_own",))
    assert visible.all()
    keypoints = {c: torch.zeros(8, 8) for c in fusion.cameras}
    keypoints["drone_own"][:, 0], keypoints["drone_own"][:, 4] = xy[:, 0, 0], xy[:, 0, 1]
    images = {c: torch.zeros(8, IMAGE_CHANNELS, 64, 64) for c in fusion.cameras}
    images["drone_own"][:, -1] = (depth[:, 0] / (UINT8_MAX * DEPTH_STEP_M))[:, None, None]
    agreeing = goal + torch.tensor([0.1, -0.1, 0.0])  # the head 14 cm off: within the gate, the camera is believed
    assert (fusion.fuse(agreeing, images, keypoints, state) - goal[:, :2]).abs().max() < 0.02
    disagreeing = goal + torch.tensor([0.3, 0.0, 0.0])  # 30 cm off: the camera sees something else; the head stays
    assert torch.equal(fusion.fuse(disagreeing, images, keypoints, state), disagreeing[:, :2])


def test_the_static_goal_filter_averages_noise_about_a_fixed_point_and_restarts_at_a_grasp():
    state, _ = _pick_states(1, torch.Generator().manual_seed(2))
    goal_world = torch.tensor([[1.05, 2.02, 0.9]])
    tcp_body = torch.tensor(get_platform("gripper").grasp_point_m)
    noise = torch.Generator().manual_seed(3)
    filtered = StaticGoalFilter(0.2, tcp_body)
    errors, raw_errors = [], []
    for step in range(60):  # the drone moves 1 cm a step towards +x; the goal stays
        state = state.clone()
        state[0, 0] += 0.01
        x_axis, y_axis = state[0, 3:6], state[0, 6:9]
        rotation = torch.stack([x_axis, y_axis, torch.linalg.cross(x_axis, y_axis)], -1)
        tcp = state[0, :3] + rotation @ tcp_body
        yaw = torch.atan2(state[0, 4], state[0, 3])
        truth = heading_frame(goal_world - tcp, yaw[None])
        seen = truth + torch.randn(1, 3, generator=noise) * 0.02
        out = filtered(seen, state, torch.tensor([False]))
        if step >= 20:
            errors.append(float((out - truth).norm()))
            raw_errors.append(float((seen - truth).norm()))
    assert sum(errors) < 0.6 * sum(raw_errors)  # averaged: well under the noise of one estimate
    grasped = filtered(truth + 0.1, state, torch.tensor([True]))
    assert torch.allclose(grasped, truth + 0.1, atol=1e-6)  # a grasp passes the estimate through
