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


def _goal_seen_by_own_camera(fusion: KeypointGoal):
    """Eight Pick states whose goal is ahead and below, in the downward-forward camera's view, with that camera's goal
    keypoint on it and the goal's depth under it: (state, goal, keypoints, images)."""
    state, task = _pick_states(8, torch.Generator().manual_seed(1))
    goal = torch.tensor([0.6, 0.1, -0.3]).expand(8, 3)
    task = task.clone()
    task[:, 8:11] = goal
    yaw = torch.atan2(state[:, 4], state[:, 3])  # the heading of the body x axis
    cy, sy = yaw.cos(), yaw.sin()
    task[:, 5:8] = torch.stack([cy * goal[:, 0] - sy * goal[:, 1], sy * goal[:, 0] + cy * goal[:, 1], goal[:, 2]], -1)
    xy, visible, depth = goal_pixels(state, task, FIELDS, get_platform("gripper"), ("drone_own",))
    assert visible.all()
    keypoints = {c: torch.zeros(8, 8) for c in fusion.cameras}
    keypoints["drone_own"][:, 0], keypoints["drone_own"][:, 4] = xy[:, 0, 0], xy[:, 0, 1]
    images = {c: torch.zeros(8, IMAGE_CHANNELS, 64, 64) for c in fusion.cameras}
    images["drone_own"][:, -1] = (depth[:, 0] / (UINT8_MAX * DEPTH_STEP_M))[:, None, None]
    return state, goal, keypoints, images


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
    fused, sighted = fusion.fuse(head, {"drone_hand": images}, {"drone_hand": keypoints}, state)
    assert sighted.all()
    # the keypoint sits in one of the image's 64 pixels: about 4 mm at these ranges
    assert (fused[:, :2] - task[:, 8:10]).abs().max() < 6e-3 and torch.equal(fused[:, 2], head[:, 2])
    far = head + torch.tensor([0.5, 0.0, 0.0])  # the head puts the goal beyond the near camera's range: its estimate
    fused, sighted = fusion.fuse(far, {"drone_hand": images}, {"drone_hand": keypoints}, state)
    assert torch.equal(fused, far) and not sighted.any()


def test_a_far_camera_is_believed_only_where_it_agrees_with_the_head():
    fusion = KeypointGoal(get_platform("gripper"), "drone_hand", far=("drone_own",), near_m=0.3, gate_m=0.2)
    state, goal, keypoints, images = _goal_seen_by_own_camera(fusion)
    agreeing = goal + torch.tensor([0.1, -0.1, 0.0])  # the head 14 cm off: within the gate, the camera is believed
    assert (fusion.fuse(agreeing, images, keypoints, state)[0][:, :2] - goal[:, :2]).abs().max() < 0.02
    disagreeing = goal + torch.tensor([0.3, 0.0, 0.0])  # 30 cm off: the camera sees something else; the head stays
    assert torch.equal(fusion.fuse(disagreeing, images, keypoints, state)[0], disagreeing)


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


def test_as_a_goal_memory_the_filter_holds_the_last_sighting_as_the_airframe_moves():
    state, _ = _pick_states(2, torch.Generator().manual_seed(4))
    tcp_body = torch.tensor(get_platform("gripper").grasp_point_m)
    memory = StaticGoalFilter(1.0, tcp_body)

    def truth_now(state: torch.Tensor, goal_world: torch.Tensor) -> torch.Tensor:
        rotation = torch.stack([state[:, 3:6], state[:, 6:9], torch.linalg.cross(state[:, 3:6], state[:, 6:9])], -1)
        tcp = state[:, :3] + (rotation @ tcp_body[:, None])[..., 0]
        return heading_frame(goal_world - tcp, torch.atan2(state[:, 4], state[:, 3]))

    goal_world = torch.tensor([[1.3, 2.1, 0.8], [0.7, 1.8, 0.8]])
    head = torch.full((2, 3), 0.5)  # a head that is far off
    no_grasp = torch.tensor([False, False])
    # before any sighting the head's estimate passes through; env 0 is sighted now, env 1 never
    out = memory(torch.stack([truth_now(state, goal_world)[0], head[1]]), state, no_grasp, torch.tensor([True, False]))
    assert torch.allclose(out[1], head[1])
    for _ in range(5):  # the airframe flies 10 cm a step; no camera sees the goal: the sighting is dead-reckoned
        state = state.clone()
        state[:, 0] += 0.1
        out = memory(head, state, no_grasp, torch.tensor([False, False]))
        assert torch.allclose(out[0], truth_now(state, goal_world)[0], atol=1e-5)
        assert torch.allclose(out[1], head[1])
    cleared = memory(head, state, torch.tensor([True, False]), torch.tensor([False, False]))  # a grasp clears it
    assert torch.allclose(cleared, head)
    memory.reset(torch.tensor([0]))
    assert torch.allclose(memory(head, state, no_grasp, torch.tensor([False, False])), head)


def test_the_spatial_softmax_spread_says_how_sure_each_keypoint_is():
    from aerobench.policies.learned import SpatialSoftmax

    maps = torch.zeros(2, 1, 12, 12)
    maps[0, 0, 3, 8] = 50.0  # one sharp peak
    spread: list[torch.Tensor] = []
    keypoints = SpatialSoftmax()(maps, spread)
    grid = torch.linspace(-1.0, 1.0, 12)
    assert torch.allclose(keypoints[0], torch.stack([grid[8], grid[3]]), atol=1e-4)  # x then y
    assert spread[0][0, 0] < 1e-3
    uniform = (2 * (13 / 33)) ** 0.5  # a flat map: the RMS distance of a 12x12 grid on [-1, 1]^2 from its centre
    assert abs(float(spread[0][1, 0]) - uniform) < 1e-4


def test_a_camera_whose_goal_keypoint_is_concentrated_is_believed_wherever_the_head_puts_the_goal():
    fusion = KeypointGoal(get_platform("gripper"), "drone_hand", far=("drone_own",), near_m=0.3, gate_m=None,
                          spread_max=0.3)
    state, goal, keypoints, images = _goal_seen_by_own_camera(fusion)
    images["drone_hand"][:, -1] = 0.5  # the hand camera sees something, diffusely
    spreads = {"drone_hand": torch.full((8, 4), 0.7), "drone_own": torch.full((8, 4), 0.7)}
    spreads["drone_own"][:4, 0] = 0.1  # the own camera's goal map is sharp in the first four
    head = goal + torch.tensor([0.4, 0.0, 0.0])  # 40 cm off: no head gate would believe the camera
    fused, sighted = fusion.fuse(head, images, keypoints, state, spreads)
    assert sighted.tolist() == [True] * 4 + [False] * 4
    assert (fused[:4, :2] - goal[:4, :2]).abs().max() < 0.02
    assert torch.equal(fused[4:], head[4:])


def test_near_the_grasp_the_vertical_offset_is_the_depth_under_the_keypoint_plus_the_named_objects_height():
    from aerobench.policies.instruction import instruction_tokens, named_phrase

    tokens = instruction_tokens(["pick up the tomato soup can from the kitchen counter",
                                 "pick up the tuna fish can from the short counter", "fly to the fridge"])
    assert named_phrase(tokens, ["can", "tomato soup can", "tuna fish can"]).tolist() == [1, 2, -1]
    platform = get_platform("gripper")
    state, task = _pick_states(3, torch.Generator().manual_seed(5))
    task = task.clone()
    task[:, 8:10] = 0.0  # right above the grasp point, 5-25 cm
    task[:, 10] = torch.tensor([-0.01, -0.02, -0.03])
    task[:, 5:8] = task[:, 8:11]  # at yaw-free offsets the env frame and the heading frame agree horizontally
    xy, visible, depth = goal_pixels(state, task, FIELDS, platform, ("drone_hand",))
    height = 0.04  # the surface under the keypoint is 4 cm above the grasp point
    from aerobench.policies.camera_input import camera_frames_in_body
    from aerobench.policies.egocentric import body_rotation

    eye = camera_frames_in_body(platform, ("drone_hand",))[0][0].float()
    eye_z = (body_rotation(state) @ (eye - torch.tensor(platform.grasp_point_m))[:, None])[:, 2, 0]  # above the TCP
    along = (task[:, 10] + height - eye_z) / (task[:, 10] - eye_z)  # where the ray to the goal meets the surface
    surface = depth[:, 0] * along  # depth along the optical axis scales along the ray
    fusion = KeypointGoal(platform, "drone_hand", near_m=0.3, depth_z={"tomato_soup_can": -height, "bowl": 0.01})
    keypoints = torch.zeros(3, 8)
    keypoints[:, 0], keypoints[:, 4] = xy[:, 0, 0], xy[:, 0, 1]
    images = torch.zeros(3, IMAGE_CHANNELS, 64, 64)
    images[:, -1] = (surface / (UINT8_MAX * DEPTH_STEP_M))[:, None, None]
    head = task[:, 8:11] + torch.tensor([0.0, 0.0, 0.03])  # the head 3 cm high
    inputs = {"drone_hand": images, "instruction": tokens}
    fused, _ = fusion.fuse(head, inputs, {"drone_hand": keypoints}, state)
    # the tomato soup can is named and within reach: its grasp point from the depth; the others keep the head's
    assert abs(float(fused[0, 2] - task[0, 10])) < 4e-3
    assert torch.equal(fused[1:, 2], head[1:, 2])
