"""The goal keypoint labels (`train.goal_pixels`): the goal point's image position computed from a dataset's recorded
state is where the env's own cameras project it, and it moves with the random-shift augmentation."""

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401  (registers the envs)
from aerobench.envs.observations import task_state_fields
from aerobench.envs.platforms import get_platform
from aerobench.policies.camera_input import random_shift
from aerobench.train.goal_pixels import goal_pixels, goal_point_world, shifted, unoccluded

CAMERAS = ("drone_front", "drone_hand", "drone_own")


def _projected(obs, camera: str, point: torch.Tensor) -> tuple[torch.Tensor, bool]:
    """The point's image position through the env's own camera matrices (OpenCV convention), as -1..1, and whether
    it is in front of the camera."""
    params = obs["sensor_param"][camera]
    extrinsic, intrinsic = params["extrinsic_cv"][0].double(), params["intrinsic_cv"][0].double()
    uvw = intrinsic @ (extrinsic[:, :3] @ point + extrinsic[:, 3])
    width = obs["sensor_data"][camera]["rgb"].shape[2]
    return 2 * (uvw[:2] / uvw[2]) / width - 1, bool(uvw[2] > 0)


@pytest.mark.parametrize("env_id", ["AeroPick-v1", "AeroPlace-v1"])
def test_goal_pixels_match_the_env_cameras(env_id):
    env = gym.make(env_id, obs_mode="rgbd", object="sugar_box")
    try:
        obs, _ = env.reset(seed=3)
        seen = 0
        for t in range(24):
            obs, *_ = env.step(torch.tensor([[0.3, 0.2, 0.1, 0.4, 1.0]]))  # turns and drifts: a tilted airframe
            if t % 6:
                continue
            state, task = obs["agent"]["state"], env.unwrapped.task_state()
            platform = get_platform("gripper")
            xy, visible, _ = goal_pixels(state, task, task_state_fields(False), platform, CAMERAS)
            goal, _ = goal_point_world(state, task, task_state_fields(False), platform.grasp_point_m)
            for c, camera in enumerate(CAMERAS):
                expected, in_front = _projected(obs, camera, goal[0])
                in_view = in_front and bool((expected.abs() <= 1).all())
                assert bool(visible[0, c]) == in_view
                if in_view:
                    assert torch.allclose(xy[0, c].double(), expected, atol=2e-3), (camera, xy[0, c], expected)
                    seen += 1
        assert seen > 0  # the goal was in some camera's view: the check compared positions inside an image
    finally:
        env.close()


def test_goal_point_is_the_marker_in_place():
    """Place's goal point is the marker: the object's bottom centre plus goal_pos, not the TCP plus it."""
    fields = task_state_fields(False)
    state = torch.zeros(1, 19)
    state[0, 3], state[0, 7] = 1.0, 1.0  # level, heading +x
    task = torch.zeros(1, sum(n for _, n in fields))
    task[0, 1] = 1.0  # place
    task[0, 5:8] = torch.tensor([0.5, 0.0, 0.0])  # goal - object bottom
    task[0, 11:14] = torch.tensor([0.0, 0.0, -0.1])  # object bottom - TCP
    goal, _ = goal_point_world(state, task, fields, (0.0, 0.0, -0.28))
    assert torch.allclose(goal[0], torch.tensor([0.5, 0.0, -0.38], dtype=torch.float64))


def test_a_label_moves_with_its_shifted_image():
    size, pad = 16, 4
    images = torch.zeros(6, 1, size, size)
    images[:, 0, 5, 9] = 1.0  # row 5, column 9
    centre = torch.tensor([[2 * 9.5 / size - 1, 2 * 5.5 / size - 1]]).repeat(6, 1)
    offsets: list[torch.Tensor] = []
    out = random_shift(images, pad, torch.Generator().manual_seed(0), offsets)
    moved = shifted(centre, offsets[0], pad, size)
    for i in range(6):
        row, col = (out[i, 0] == 1.0).nonzero()[0].tolist()
        assert torch.allclose(moved[i], torch.tensor([2 * (col + 0.5) / size - 1, 2 * (row + 0.5) / size - 1]))


def test_a_goal_behind_something_nearer_is_not_a_label():
    depth_levels = torch.full((3, 8, 8), 50, dtype=torch.uint8)  # 1 m everywhere (levels of 2 cm)
    depth_levels[1, 2, 6] = 10  # 0.2 m: the palm in front of the goal's pixel
    depth_levels[2, 2, 6] = 0  # no return: nothing in front
    xy = torch.tensor([[0.6, -0.4]]).repeat(3, 1)  # pixel (column 6, row 2)
    visible = unoccluded(torch.ones(3, dtype=torch.bool), xy, torch.full((3,), 1.05), depth_levels, 0.02)
    assert visible.tolist() == [True, False, True]
