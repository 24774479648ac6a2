"""A pick that follows another chain stage backs away from where that stage left the drone, then flies a planned route
to a staging point in front of the pre-grasp point; the fridge is opened wider before a pick from its shelf, and the
transport after it backs out and folds the arm (docs/expert.md, LongHorizonRearrangement)."""

import math

import gymnasium as gym
import numpy as np
import torch

import aerobench.envs  # noqa: F401
from aerobench.envs.scenes import articulated
from aerobench.expert import ExpertController
from aerobench.expert.articulation import OPEN_FOR_REACH_IN, ArticulationExpert
from aerobench.expert.nav import BACK_OUT_M, NavExpert
from aerobench.expert.pick import BACK_OFF_M, STAGING_M, PickExpert, PickPhase
from aerobench.expert.planner import planner_for
from aerobench.rollout.runner import SEED_STRIDE

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


def test_the_fridge_opens_wider_before_a_pick_from_its_shelf_and_the_drawer_does_not():
    for chain, wide in (("open_pick_nav_place", True), ("open_pick_nav_place_close", False)):
        env = gym.make("AeroSequential-v1", obs_mode="state_dict", setting="LongHorizonRearrangement", chain=chain)
        env.reset(seed=20000060, options={"reconfigure": True, "objects": ["sugar_box"]})
        opener = ExpertController(env.unwrapped).experts[0]
        assert isinstance(opener, ArticulationExpert) and opener.reach_in_next is wide, chain
        env.close()
    assert OPEN_FOR_REACH_IN > articulated.get_fixture_spec("fridge").open_threshold


def test_the_transport_after_a_fridge_pick_backs_out_then_flies_with_the_arm_folded():
    env = gym.make("AeroSequential-v1", obs_mode="state_dict", setting="LongHorizonRearrangement",
                   chain="open_pick_nav_place")
    env.reset(seed=20000061, options={"reconfigure": True, "objects": ["sugar_box"]})
    base = env.unwrapped
    nav = ExpertController(base).experts[2]
    assert isinstance(nav, NavExpert) and nav.after_pick is base.evaluators[1] and bool(base.evaluators[1].enclosed[0])
    state = base.agent.airframe_state()
    nav.reset(ENV0)
    yaw = float(state.yaw[0])
    backed = nav.route.points[0, 0] - state.position[0]
    assert torch.allclose(backed, -BACK_OUT_M * torch.tensor([math.cos(yaw), math.sin(yaw), 0.0]), atol=1e-5)
    assert bool(nav.backing[0])
    # folded, the arm and the fingers stay within the rotor disks' outline (plus the fingers' half opening);
    # at the working pose they reach 0.47 m ahead
    disks = base.platform.rotors.arm_m * math.sqrt(2) + base.platform.rotors.disk_radius_m
    folded = planner_for(base, 0, heading=0.0, arm_q=nav.carry_pose).footprint
    working = planner_for(base, 0, heading=0.0).footprint
    assert np.linalg.norm(folded[:, :2], axis=-1).max() < disks + 0.08
    assert np.linalg.norm(working[:, :2], axis=-1).max() > 0.5
    env.close()


def test_the_arm_grasps_top_down_from_the_side_with_room_for_its_rotors():
    # drawer chain, eval seed 22, episode 74: a sugar box on a counter against a wall; the grasp heading nearer the
    # drone's yaw after the opening stood the airframe 5 cm into the wall, and the pick flew into it
    from aerobench.envs.skills.pick import grasp_heading

    env = gym.make("AeroSequential-v1", obs_mode="state_dict", setting="LongHorizonRearrangement", chain="open_pick_nav_place_close")
    try:
        env.reset(seed=22 * SEED_STRIDE + 74, options={"reconfigure": True, "objects": ["sugar_box"]})
        base = env.unwrapped
        controller = ExpertController(base)
        controller.reset(torch.arange(1))
        for _ in range(600):
            env.step(controller.act())
            if int(controller.stage[0]) == 1:
                break
        pick = controller.experts[1].evaluator
        assert int(controller.stage[0]) == 1 and bool(base.platform.arm is not None) and not bool(pick.enclosed[0])
        q = base.target.pose.q
        nearer = grasp_heading(2 * torch.atan2(q[:, 3], q[:, 0]), controller.experts[1].state().yaw, pick.is_round)
        assert abs(math.remainder(float(pick.heading[0] - nearer[0]), 2 * math.pi)) > 3.0  # the other way round
        room = lambda h: float(pick._roomiest_top_down_heading(h)[0])  # noqa: E731
        assert room(pick.heading) == float(pick.heading[0])  # the planned heading has room: kept
        assert room(nearer) != float(nearer[0])  # the nearer one had not
    finally:
        env.close()
