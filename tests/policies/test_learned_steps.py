"""A learned policy's control step stays on the env's device: after an episode's first observation, `act` reads no
tensor value on the host (the sync detector of tests/envs/host_sync.py), with cameras, history and instruction."""

import gymnasium as gym
import pytest
import torch

import aerobench.envs  # noqa: F401
from aerobench.policies import make_policy
from aerobench.threads import torch_threads
from tests.envs.host_sync import NoHostSync

CHECKPOINTS = {
    "privileged": "leaderboards/checkpoints/PrepareGroceries/bc/place",
    "vision": "leaderboards/checkpoints/PrepareGroceries/bc_vision/place_h10",  # cameras, 10 frames, instruction
}


@pytest.mark.parametrize("tier", sorted(CHECKPOINTS))
def test_a_learned_policy_acts_without_a_host_sync_between_resets(tier):
    obs_mode = "rgbd" if tier == "vision" else "state_dict"
    with torch_threads(1):
        env = gym.make("AeroPlace-v1", num_envs=1, obs_mode=obs_mode, setting="PrepareGroceries")
        obs, _ = env.reset(seed=3)
        policy = make_policy("bc", env.unwrapped, checkpoint=CHECKPOINTS[tier])
        policy.reset(torch.arange(1))
        obs, *_ = env.step(policy.act(obs))  # the episode's first observation: the instruction is looked up
        for _ in range(2):
            with NoHostSync():
                action = policy.act(obs)
            assert action.device == env.unwrapped.device and action.shape == (1, 5)
            obs, *_ = env.step(action)
        policy.reset(torch.arange(1))  # a new episode renews the instruction and the history, then no sync again
        policy.act(obs)
        with NoHostSync():
            policy.act(obs)
        env.close()


def test_the_close_threshold_moves_the_release_decision_and_defaults_to_the_logits_sign():
    from aerobench.policies.learned import Normalizer, env_action, identity_stats

    normalizer = Normalizer(identity_stats(3, 5))
    out = torch.zeros(3, 5)
    out[:, -1] = torch.tensor([-1.0, 0.5, 2.5])  # P(close) = 0.27, 0.62, 0.92
    assert env_action(out, normalizer, "binary")[:, -1].tolist() == [1.0, -1.0, -1.0]  # -1: close
    assert env_action(out, normalizer, "binary", close_threshold=0.9)[:, -1].tolist() == [1.0, 1.0, -1.0]
    assert torch.equal(env_action(out, normalizer, "binary", close_threshold=0.5),
                       env_action(out, normalizer, "binary"))
