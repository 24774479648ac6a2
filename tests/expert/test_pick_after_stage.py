"""A pick that follows another chain stage backs away from where that stage left the drone, then flies a planned route
to a staging point in front of the pre-grasp point (docs/expert.md, LongHorizonRearrangement)."""

import math

import gymnasium as gym
import torch

import aerobench.envs  # noqa: F401
from aerobench.expert import ExpertController
from aerobench.expert.pick import BACK_OFF_M, STAGING_M, PickExpert, PickPhase

ENV0 = torch.tensor([0])


def test_a_pick_after_opening_the_fridge_backs_off_then_stages_in_front_of_it():
    env = gym.make("AeroSequential-v1", obs_mode="state_dict", setting="LongHorizonRearrangement",
                   chain="open_pick_nav_place")
    env.reset(seed=20000060, options={"reconfigure": True, "objects": ["master_chef_can"]})
    base = env.unwrapped
    controller = ExpertController(base)
    first, pick = controller.experts[0], controller.experts[1]
    assert isinstance(pick, PickExpert) and pick.after_stage and not getattr(first, "after_stage", False)
    base.evaluators[1].begin(ENV0)
    state = base.agent.airframe_state()
    pick.reset(ENV0)
    assert int(pick.phase[0]) == PickPhase.ROUTE
    waypoints = pick.route.points[0, : int(pick.route.length[0])]
    yaw = float(state.yaw[0])
    backed = waypoints[0] - state.position[0]
    assert torch.allclose(backed, -BACK_OFF_M * torch.tensor([math.cos(yaw), math.sin(yaw), 0.0]), atol=1e-5)
    # the route ends where the tool centre point, turned to the grasp heading, is STAGING_M before the pre-grasp point
    heading = float(pick.heading[0])
    along = torch.tensor([math.cos(heading), math.sin(heading), 0.0])
    tcp_body = base.agent.tcp_pose.p[0] - state.position[0]
    turn = heading - yaw
    tcp_at_heading = torch.tensor([math.cos(turn) * tcp_body[0] - math.sin(turn) * tcp_body[1],
                                   math.sin(turn) * tcp_body[0] + math.cos(turn) * tcp_body[1], tcp_body[2]])
    pre = pick.pre_grasp(pick.grasp_point())[0]
    assert torch.allclose(waypoints[-1] + tcp_at_heading + STAGING_M * along, pre, atol=1e-4)
    env.close()
