"""The look-first Pick expert (`aerobench generate --look-first`): it turns on the spot, one fixed way while the
object is out of the front camera's view, until the object is ahead; then it plans the grasp heading from there and
picks as the plain expert does (docs/datasets.md, "Demonstrations for camera policies")."""

import math

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401
from aerobench.envs.observations import wrap_angle
from aerobench.envs.skills.pick import grasp_heading
from aerobench.expert import ExpertController
from aerobench.expert.look import IN_VIEW_RAD, LOOK_DONE_RAD, LOOK_YAW_RATE_RPS, LookFirst, look_yaw_rate
from aerobench.rollout.runner import SEED_STRIDE, RolloutSpec


def test_the_turn_is_one_fixed_way_out_of_view_and_towards_the_object_in_view():
    bearing = torch.tensor([2.5, -2.5, math.pi, -(IN_VIEW_RAD + 0.01), 0.3, -0.3, 0.0])
    rate = look_yaw_rate(bearing)
    assert torch.allclose(rate[:4], torch.full((4,), LOOK_YAW_RATE_RPS))  # behind, either side: counter-clockwise
    assert rate[4] > 0 and rate[5] < 0 and rate[6] == 0  # in view: towards it, slowing to rest as it comes ahead
    assert rate[4] == -rate[5] and abs(rate[4]) <= LOOK_YAW_RATE_RPS


def test_a_start_facing_away_turns_in_place_until_the_object_is_ahead_then_picks_it():
    env = gym.make("AeroPick-v1", obs_mode="state_dict", setting="PrepareGroceries")
    base = env.unwrapped
    env.reset(seed=111 * SEED_STRIDE + 3, options={"reconfigure": True, "objects": ["tuna_fish_can"]})
    controller = ExpertController(base, look_first=True)
    controller.reset(torch.tensor([0]))
    look = controller.experts[0]
    assert isinstance(look, LookFirst)
    bearing, _ = look.bearing()
    assert abs(float(bearing[0])) > math.radians(90)  # this start has the can behind the drone's left shoulder
    start = base.agent.airframe_state().position[0].clone()
    yaws, handed_over, success = [], None, False
    for t in range(400):
        before = bool(look.looking[0])
        _, _, terminated, truncated, info = env.step(controller.act())
        state = base.agent.airframe_state()
        if before and not bool(look.looking[0]):
            handed_over = t
            bearing, _ = look.bearing()
            assert abs(float(bearing[0])) < LOOK_DONE_RAD + 0.05
            # the grasp heading was planned again from the heading it looks along now (a round can: the room axis
            # nearest to it), not from the start's
            replanned = grasp_heading(torch.zeros(1), state.yaw[:1], torch.ones(1, dtype=torch.bool))
            assert abs(float(wrap_angle(look.expert.heading[0] - replanned[0]))) < 0.1
        if bool(look.looking[0]):
            yaws.append(float(state.yaw[0]))
            assert torch.linalg.norm(state.position[0, :2] - start[:2]) < 0.05  # on the spot
        if bool(terminated[0] | truncated[0]):
            success = bool(info["success"][0])
            break
    assert handed_over is not None and handed_over > 20
    turned = [wrap_angle(torch.tensor(b - a)) for a, b in zip(yaws, yaws[1:])]
    assert all(float(d) > -1e-3 for d in turned)  # counter-clockwise all the way round (the can was out of view)
    assert success


@pytest.mark.parametrize("overrides, message", [
    ({"skills": ("place",)}, "give --skills pick"),
    ({"policy": "bc", "checkpoint": "x"}, "--label-with expert"),
])
def test_look_first_is_refused_where_it_means_nothing(overrides, message):
    kwargs = dict(setting="PrepareGroceries", skills=("pick",), episodes=1, look_first=True) | overrides
    with pytest.raises(ValueError, match=message):
        RolloutSpec(**kwargs)


def test_a_look_first_run_says_so_in_its_identity():
    spec = RolloutSpec(setting="PrepareGroceries", skills=("pick",), episodes=1, look_first=True)
    assert spec.as_dict()["look_first"] is True
    assert "look_first" not in RolloutSpec(setting="PrepareGroceries", skills=("pick",), episodes=1).as_dict()


def test_look_first_labels_a_learned_policys_flight():
    # DAgger on a policy cloned from look-first demonstrations: the labelling expert looks first, the policy flies
    spec = RolloutSpec(setting="PrepareGroceries", skills=("pick",), episodes=1, look_first=True, policy="bc",
                       checkpoint="x", labeler="expert")
    assert spec.as_dict()["look_first"] is True and spec.as_dict()["labeler"] == "expert"
