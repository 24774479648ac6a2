"""Every registered aerobench env id and setting through the env checker (aerobench.envs.checker)."""

import pytest

from aerobench.envs.checker import check_env, env_configs

CONFIGS = env_configs()


def test_every_setting_skill_and_chain_is_covered():
    ids = {(env_id, kwargs["setting"], kwargs.get("chain")) for env_id, kwargs in CONFIGS}
    assert ("AeroPick-v1", "TidyHouse", None) in ids and ("AeroOpen-v1", "PrepareGroceries", None) in ids
    assert ("AeroSequential-v1", "PackageDelivery", "deliver") in ids
    assert len(CONFIGS) == 21


@pytest.mark.parametrize("env_id, kwargs", CONFIGS, ids=[f"{e}-{'-'.join(k.values())}" for e, k in CONFIGS])
def test_env_checker(env_id, kwargs):
    check_env(env_id, **kwargs)


@pytest.mark.parametrize("obs_mode", ["rgbd", "state"])
def test_gymnasiums_checker_passes_the_space_checks_and_stops_where_maniskills_own_env_does(obs_mode):
    """gymnasium's `check_env`: the observation and action spaces and the reset's observation pass (an rgbd
    observation's `extra` was once an empty Dict, which gymnasium refuses); the checker then stops at ManiSkill's
    reset, which seeds its own generators rather than gymnasium's `np_random`, exactly as ManiSkill's PickCube-v1
    does (docs/skills.md)."""
    import gymnasium as gym
    from gymnasium.utils import env_checker

    import aerobench.envs  # noqa: F401

    seed_message = "Expects the random number generator to have been generated given a seed was passed to reset"
    for env_id in ("AeroPick-v1", "PickCube-v1"):
        env = gym.make(env_id, obs_mode=obs_mode).unwrapped
        env_checker.check_observation_space(env.observation_space)
        env_checker.check_action_space(env.action_space)
        obs, _ = env.reset(seed=0)
        if obs_mode == "rgbd":  # "state" flattens everything into one vector
            assert obs["extra"], "an empty Dict observation space is refused by gymnasium"
        with pytest.raises(AssertionError, match=seed_message):
            env_checker.check_env(env, skip_render_check=True)
        env.close()
