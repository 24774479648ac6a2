"""The random baseline: each episode draws its own actions from its own seed (it once replayed one sequence in every
episode: a generator seeded with 0 and made anew per batch)."""

import gymnasium as gym
import torch

import aerobench.envs  # noqa: F401
from aerobench.policies import make_policy


def _actions(env, seed: int, steps: int = 12) -> torch.Tensor:
    obs, _ = env.reset(seed=seed)
    policy = make_policy("random", env.unwrapped)  # the runner builds a policy per batch
    policy.reset(torch.arange(1))
    return torch.stack([policy.act(obs)[0] for _ in range(steps)])


def test_random_episodes_differ_by_seed_and_an_episode_replays_its_own_actions():
    env = gym.make("AeroPick-v1", obs_mode="state_dict")
    first, second, again = _actions(env, 1), _actions(env, 2), _actions(env, 1)
    env.close()
    assert not torch.equal(first, second) and torch.equal(first, again)
    assert torch.equal(first[0], first[4]) and not torch.equal(first[4], first[5])  # held for 5 control steps
    assert first.abs().max() <= 1.0
