"""DART noise injection: the env executes the policy's action plus noise on the flight commands, the episode records
the policy's own action, and a run names its noise (so a dataset resumed without it is refused)."""

import gymnasium as gym
import numpy as np
import pytest
import torch

from aerobench.rollout.episode import EpisodeList
from aerobench.rollout.noise import FLIGHT_ACTION_DIMS, ActionNoise, check_action_noise
from aerobench.rollout.runner import RolloutRunner, RolloutSpec


def test_noise_perturbs_only_the_flight_commands_reproducibly_and_within_bounds():
    action = torch.tensor([[0.1, -0.2, 0.3, 0.0, -1.0], [0.99, 0.0, 0.0, 0.0, 1.0]])
    first, second = ActionNoise(0.3, seeds=[5, 9])(action), ActionNoise(0.3, seeds=[5, 9])(action)
    assert torch.equal(first, second)  # same seeds, same noise
    assert not torch.equal(first[:, :FLIGHT_ACTION_DIMS], action[:, :FLIGHT_ACTION_DIMS])
    assert torch.equal(first[:, FLIGHT_ACTION_DIMS:], action[:, FLIGHT_ACTION_DIMS:])  # the gripper is never perturbed
    assert first.abs().max() <= 1.0
    assert not torch.equal(ActionNoise(0.3, seeds=[6, 9])(action)[0], first[0])
    assert torch.equal(ActionNoise(0.3, seeds=[6, 9])(action)[1], first[1])  # a row's noise is its own seed's
    assert torch.equal(ActionNoise(0.3, seeds=[9, 5])(action[[1, 0]]), first[[1, 0]])  # in any row of any batch
    assert torch.equal(ActionNoise(0.0, seeds=[5, 9])(action), action)
    assert torch.equal(action[0], torch.tensor([0.1, -0.2, 0.3, 0.0, -1.0]))  # the caller's tensor is untouched
    noise = ActionNoise(0.3, seeds=[5, 9])
    noise(action)
    noise.restart([0], [5])  # env 0 begins another episode of seed 5: its noise starts again, env 1's continues
    again = noise(action)
    assert torch.equal(again[0], first[0]) and not torch.equal(again[1], first[1])


@pytest.mark.parametrize("sigma", [-0.1, float("nan"), 0.7, "0.1"])
def test_bad_noise_is_one_clear_error(sigma):
    with pytest.raises(ValueError, match="--action-noise must be a standard deviation between 0 and 0.5"):
        check_action_noise(sigma)
    with pytest.raises(ValueError, match="--action-noise must be"):
        RolloutSpec(setting="TidyHouse", skills=("nav",), episodes=1, action_noise=sigma)


def test_a_run_names_its_noise_and_noise_free_runs_keep_their_old_spec():
    assert "action_noise" not in RolloutSpec(setting="TidyHouse", skills=("nav",), episodes=1).as_dict()
    assert RolloutSpec(setting="TidyHouse", skills=("nav",), episodes=1, action_noise=0.05).as_dict()["action_noise"] == 0.05


class _Executed(gym.Wrapper):
    """Keeps what the env was actually given."""

    def __init__(self, env):
        super().__init__(env)
        self.executed = []
        self._max_episode_steps = env._max_episode_steps  # the time limit the runner reads

    def step(self, action):
        self.executed.append(action.detach().cpu().numpy().copy())
        return super().step(action)


def test_the_episode_records_the_experts_action_while_the_env_executes_the_perturbed_one(monkeypatch):
    spec = RolloutSpec(setting="TidyHouse", skills=("nav",), episodes=1, seed=3, record_cameras=False, max_steps=12,
                       action_noise=0.2)
    sink = EpisodeList()
    runner = RolloutRunner(spec, sink)
    make_env = runner._env
    wrapped = {}

    def env_with_spy(skill):
        if skill not in wrapped:
            wrapped[skill] = _Executed(make_env(skill))
        return wrapped[skill]

    monkeypatch.setattr(runner, "_env", env_with_spy)
    runner.run()
    recorded = sink.episodes[0].frames["action"]
    executed = np.concatenate(wrapped["nav"].executed)[: len(recorded)]
    difference = executed - recorded
    assert np.abs(difference[:, :FLIGHT_ACTION_DIMS]).max() > 0.05  # the env flew the perturbed commands
    assert np.std(difference[:, :FLIGHT_ACTION_DIMS]) == pytest.approx(0.2, rel=0.5)
    assert np.array_equal(executed[:, FLIGHT_ACTION_DIMS:], recorded[:, FLIGHT_ACTION_DIMS:])
