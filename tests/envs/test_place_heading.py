"""The arm platform's place turns where the airframe would stand in a wall at the release (docs/expert.md, "The
place's heading"); the gripper platform's place keeps the heading it begins with."""

import math

import gymnasium as gym
import torch

import aerobench.envs  # noqa: F401
from aerobench.envs.control.arm import arm_point_positions_body
from aerobench.envs.geometry import level_airframe_room, pack_boxes
from aerobench.envs.scenes.layout import Box
from aerobench.envs.skills.place import PLACE_ROOM_M, PlaceEvaluator
from aerobench.envs.tasks import get_setting
from aerobench.rollout.runner import SEED_STRIDE


def test_level_airframe_room_is_the_proxy_points_distance_to_a_wall():
    # a wall whose face is the plane x = 1; the airframe's grasp point 0.3 m ahead of its centre
    boxes = pack_boxes([[Box(name="wall", center=(1.5, 0.0, 1.0), half_size=(0.5, 5.0, 2.0), yaw=0.0)]])
    points = torch.tensor([[0.2, 0.0, 0.0], [-0.1, 0.1, 0.05]])
    grasp_body = torch.tensor([[0.3, 0.0, -0.2]])
    grasp = torch.tensor([[[0.6, 0.0, 1.0], [0.6, 0.0, 1.0]]])
    room = level_airframe_room(grasp, torch.tensor([[0.0, math.pi]]), grasp_body, boxes, points, 0.01)
    # facing +x the centre is at x = 0.3 and its farthest point forward at 0.5; facing -x the centre is at 0.9 and the
    # point 0.1 behind it (body x = -0.1) at 1.0, on the wall's face
    assert torch.allclose(room, torch.tensor([[1.0 - 0.5 - 0.01, 1.0 - 1.0 - 0.01]]), atol=1e-6)


def _fridge_chain(index: int):
    objects = get_setting("LongHorizonRearrangement").objects
    env = gym.make("AeroSequential-v1", obs_mode="state_dict", setting="LongHorizonRearrangement",
                   chain="open_pick_nav_place")
    env.reset(seed=22 * SEED_STRIDE + index, options={"reconfigure": True, "objects": [objects[index % len(objects)]]})
    return env


def test_an_arm_place_by_a_wall_turns_to_face_it():
    # fridge chain, eval seed 22, episode 73: the cracker box's goal is on a counter against the wall at x = 4.5; the
    # chain arrived facing away from the wall (yaw -3.12), the arm ahead over the goal and the airframe in the wall
    env = _fridge_chain(73)
    try:
        base = env.unwrapped
        place = next(e for e in base.evaluators if isinstance(e, PlaceEvaluator))
        assert place.after_pick is not None and bool(place.after_pick.enclosed[0])
        i = torch.arange(1)
        position = base.agent.airframe_state().position[i]
        chosen = {}
        for yaw in (-3.12, 0.0, 0.4):
            base.set_drone(i, position, torch.tensor([yaw]))
            chosen[yaw] = float(place.place_heading(i)[0])
        assert abs(chosen[-3.12]) < math.pi / 4 + 1e-3  # turned to face the wall (the roomiest eighth turn)
        assert chosen[0.0] == 0.0 and math.isclose(chosen[0.4], 0.4, abs_tol=1e-6)  # room enough: kept
        # the room the chosen heading leaves, measured as the function does
        arm = base.platform.arm
        grasp = arm_point_positions_body(torch.tensor([arm.carry_pose_rad]), arm)["grasp"]
        release = place.goal[i] + torch.tensor([0.0, 0.0, float(base.target_grasp_point[0, 2])])
        room = level_airframe_room(release[:, None], torch.tensor([[chosen[-3.12], -3.12]]), grasp,
                                   base.obstacle_boxes(i), base.proxy_points, base.proxy_radius)
        assert float(room[0, 0]) >= PLACE_ROOM_M > float(room[0, 1])
    finally:
        env.close()


def test_the_gripper_platforms_place_keeps_its_heading():
    env = gym.make("AeroPlace-v1", obs_mode="state_dict", setting="TidyHouse")
    try:
        env.reset(seed=3, options={"reconfigure": True})
        base = env.unwrapped
        place = base.evaluators[0]
        i = torch.arange(1)
        position = base.agent.airframe_state().position[i]
        for yaw in (-3.0, 0.0, 1.2):
            base.set_drone(i, position, torch.tensor([yaw]))
            assert math.isclose(float(place.place_heading(i)[0]), yaw, abs_tol=1e-6)
    finally:
        env.close()
