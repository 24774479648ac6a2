"""Goal markers: where the scene shows Place's spot and Nav's target, and that nothing but the pictures changes."""

import gymnasium as gym
import numpy as np
import pytest
import torch

import aerobench.envs  # noqa: F401
from aerobench.envs.skills import markers
from aerobench.envs.skills.nav import NavEvaluator
from aerobench.envs.skills.place import GOAL_MARKER, PlaceEvaluator
from aerobench.envs.skills.starts import PARKING_DEPTH_M
from aerobench.policies import make_policy


def _marker(base, skill):
    return next(actor for evaluator, actor in base.goal_markers if evaluator.skill == skill)


def test_the_place_marker_lies_on_the_goal_and_the_instruction_names_it():
    env = gym.make("AeroPlace-v1", setting="PrepareGroceries", obs_mode="state_dict")
    env.reset(seed=3)
    base = env.unwrapped
    goal = base.evaluators[0].goal[0]
    p = _marker(base, "place").pose.p[0]
    assert torch.allclose(p[:2], goal[:2]) and float(p[2] - goal[2]) == pytest.approx(GOAL_MARKER.lift_m, abs=1e-5)
    assert "on the marked spot of" in base.get_instruction(0)
    env.close()


def test_a_named_nav_target_is_marked_and_a_target_the_chain_sets_is_not():
    env = gym.make("AeroNav-v1", setting="PrepareGroceries", obs_mode="state_dict")
    env.reset(seed=1)
    base = env.unwrapped
    assert torch.allclose(_marker(base, "nav").pose.p[0], base.evaluators[0].target[0])
    assert base.get_instruction(0).startswith("fly to the marker at ")
    env.close()
    chain = gym.make("AeroSequential-v1", setting="TidyHouse", obs_mode="state_dict")
    chain.reset(seed=2)
    base = chain.unwrapped
    assert float(_marker(base, "nav").pose.p[0, 2]) == pytest.approx(PARKING_DEPTH_M)  # above the place goal: parked
    assert float(_marker(base, "place").pose.p[0, 2]) > 0.0
    assert base.skill_instruction(0).startswith("pick up the ")  # the active stage's instruction
    chain.close()


def _expert_flight(monkeypatch, with_markers: bool, env_id: str, seed: int, steps: int) -> np.ndarray:
    if not with_markers:
        monkeypatch.setattr(PlaceEvaluator, "marker", None)
        monkeypatch.setattr(NavEvaluator, "marker", None)
    env = gym.make(env_id, setting="PrepareGroceries", obs_mode="state_dict")
    obs, _ = env.reset(seed=seed)
    base = env.unwrapped
    assert bool(base.goal_markers) == with_markers
    expert = make_policy("expert", base)
    expert.reset(torch.arange(1))
    trace = []
    for _ in range(steps):
        action = expert.act(obs)
        obs, *_ = env.step(action)
        trace.append(torch.cat([obs["agent"]["state"][0], base.task_state()[0], action[0]]).numpy())
    env.close()
    monkeypatch.undo()
    return np.stack(trace)


@pytest.mark.parametrize("env_id, seed", [("AeroPlace-v1", 5), ("AeroNav-v1", 2)])
def test_markers_change_nothing_the_simulation_the_expert_or_the_task_state_see(monkeypatch, env_id, seed):
    with_markers = _expert_flight(monkeypatch, True, env_id, seed, 120)
    without = _expert_flight(monkeypatch, False, env_id, seed, 120)
    assert np.array_equal(with_markers, without)  # bit for bit: proprio state, task state and the expert's actions


def test_a_marker_is_a_disc_or_a_sphere():
    with pytest.raises(ValueError, match="a disc or a sphere"):
        markers.MarkerShape("cube", 0.1)
