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
