"""A pick from a fridge shelf is one the arm platform can make: the object stands where the arm reaches it from in
front of the fridge with the rotor disks clear of the carcass and of the open door (`skills.pick`, ENCLOSED_*)."""

from __future__ import annotations

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401
from aerobench.envs.geometry import body_points_to_world, drone_proxy_points_body, point_box_distance
from aerobench.envs.platforms import get_platform
from aerobench.envs.scenes import articulated
from aerobench.envs.skills.pick import ENCLOSED_ROTOR_CLEARANCE_M, enclosed_reach_m
from aerobench.expert.articulation import OPEN_FOR_REACH_IN

ENV0 = torch.tensor([0])


def test_the_reach_into_an_enclosure_is_the_arm_minus_the_rotor_disks():
    """Hand computation, straight in: 0.47 m to the tool centre point, disks 0.174 + 0.147 m ahead, 3.5 cm clear."""
    reach, disks, sideways = enclosed_reach_m(get_platform("arm"), yaw_noise=0.0)
    assert disks == pytest.approx(0.174 + 0.147)
    assert reach == pytest.approx(0.47 - 0.321 - ENCLOSED_ROTOR_CLEARANCE_M)
    assert sideways == pytest.approx(0.0)
    # every class fits in front of the board's 2 cm setback, the cracker box (0.158 m deep) the tightest
    assert reach >= articulated.FRIDGE_SHELF_SETBACK_M + 0.158 / 2 + 0.005


@pytest.mark.parametrize("obj", ["cracker_box", "bowl", "tuna_fish_can"])
def test_at_the_grasp_the_rotor_disks_clear_the_fridge_and_its_open_door(obj):
    env = gym.make("AeroSequential-v1", obs_mode="state_dict", setting="LongHorizonRearrangement",
                   chain="open_pick_nav_place")
    base = env.unwrapped
    platform = base.platform
    rim_points, rim_radius = drone_proxy_points_body(platform)
    for seed in (20000060, 20000061, 20000062):
        _, info = env.reset(seed=seed, options={"reconfigure": True, "objects": [obj]})
        assert not bool(info["init_failed"][0]), seed
        pick = base.evaluators[1]
        assert pick.skill == "pick" and bool(pick.enclosed[0])
        fridge = base.built.fixtures["fridge"]
        fridge.set_qpos(torch.tensor([[OPEN_FOR_REACH_IN * articulated.FRIDGE_DOOR_MAX_RAD]]))
        heading = pick.heading[0]
        grasp = pick.grasp_target(base.agent.tcp_pose.p)[0]
        c, s = torch.cos(heading), torch.sin(heading)
        rotation = torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        centre = grasp - rotation @ torch.tensor(platform.grasp_point_m)
        points = body_points_to_world(rim_points, centre[None], rotation[None])
        clearance = float(point_box_distance(points, base.obstacle_boxes(ENV0)).min()) - rim_radius
        assert clearance > 0.01, (seed, clearance)
        # ... while the object stands inside the fridge, behind its front, on the latch half of the shelf
        shelf = base.supports[0, pick.support_index[0]]
        along = torch.stack([torch.cos(shelf[5]), torch.sin(shelf[5])])  # the shelf's +x: out of the fridge
        behind_front = float((shelf[0:2] - base.target.pose.p[0, :2]) @ along) + float(shelf[2]) + articulated.SUPPORT_EDGE_MARGIN_M + articulated.FRIDGE_SHELF_SETBACK_M
        assert 0.02 < behind_front < 0.47 - 0.321, (seed, behind_front)
    env.close()


@pytest.mark.parametrize("obj, seed", [("sugar_box", 22 * 1_000_003 + 47), ("gelatin_box", 20000060), ("tuna_fish_can", 20000061)])
def test_on_a_fridge_shelf_the_open_fingers_clear_the_side_wall(obj, seed):
    # the fingers close across the way in, their open pads 55 mm and their outer faces 65 mm either side of the grasp
    # point: a sugar box 5 mm off the fridge's side wall (seed 22's episode 47) left the far finger in the wall, and
    # the grasp never closed
    env = gym.make("AeroSequential-v1", obs_mode="state_dict", setting="LongHorizonRearrangement",
                   chain="open_pick_nav_place")
    base = env.unwrapped
    gripper = base.platform.gripper
    _, info = env.reset(seed=seed, options={"reconfigure": True, "objects": [obj]})
    assert not bool(info["init_failed"][0])
    pick = base.evaluators[1]
    assert bool(pick.enclosed[0])
    shelf = base.supports[0, pick.support_index[0]]
    across = torch.stack([-torch.sin(shelf[5]), torch.cos(shelf[5])])  # the shelf's y: across the fridge
    side = float((base.target.pose.p[0, :2] - shelf[0:2]) @ across)
    to_wall = articulated.FRIDGE_WIDTH_M / 2 - articulated.FRIDGE_WALL_M - abs(side)
    assert to_wall >= gripper.max_opening_m / 2 + gripper.finger_thickness_m, (side, to_wall)
    env.close()
