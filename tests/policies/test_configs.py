"""`configs/` holds one LeRobot training config per policy and setting. The TidyHouse configs run end to end in the
other tests here; every other setting's config must be the same config pointed at that setting's dataset."""

import json
from pathlib import Path

import pytest

from aerobench.envs.tasks import SETTINGS, snake_name

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
POLICIES = ("act", "diffusion", "pi0", "pi05", "act_state", "diffusion_state", "act_cpu", "diffusion_cpu")


def test_there_is_exactly_one_config_per_policy_and_setting():
    expected = {f"{p}_{snake_name(s)}.json" for p in POLICIES for s in SETTINGS}
    assert {p.name for p in CONFIGS.glob("*.json")} == expected
    assert "pi05_long_horizon_rearrangement.json" in expected


@pytest.mark.parametrize("policy", POLICIES)
@pytest.mark.parametrize("setting", [s for s in SETTINGS if s != "TidyHouse"])
def test_a_setting_config_is_the_tidy_house_config_on_that_settings_data(policy, setting):
    name = snake_name(setting)
    config = json.loads((CONFIGS / f"{policy}_{name}.json").read_text())
    reference = json.loads((CONFIGS / f"{policy}_tidy_house.json").read_text())
    suffix = "_state" if policy.endswith("_state") else ""  # state-only variants train on state-only exports
    assert config["dataset"] == {**reference["dataset"], "repo_id": f"local/aerobench_{name}{suffix}",
                                 "root": f"data/{name}{suffix}"}
    assert (config["output_dir"], config["job_name"]) == (f"outputs/train/{policy}_{name}", f"{policy}_{name}")
    if "path" in reference["policy"]:  # pi0 / pi0.5: the folder `aerobench pi-init` writes for this setting
        assert config["policy"] == {**reference["policy"], "path": f"outputs/pi/{policy}_{name}"}
    elif "observation.environment_state" in reference["policy"].get("input_features", {}):
        # the task state is as wide as the setting's platform's: the arm adds its joint angles
        from aerobench.envs.observations import task_state_fields
        from aerobench.envs.tasks import SETTINGS as TASK_SETTINGS

        width = sum(n for _, n in task_state_fields(with_arm=TASK_SETTINGS[setting].chain_platform == "arm"))
        features = {**reference["policy"]["input_features"],
                    "observation.environment_state": {"type": "ENV", "shape": [width]}}
        assert config["policy"] == {**reference["policy"], "input_features": features}
    else:
        assert config["policy"] == reference["policy"]
    rest = {k: v for k, v in config.items() if k not in ("dataset", "output_dir", "job_name", "policy")}
    assert rest == {k: v for k, v in reference.items() if k not in ("dataset", "output_dir", "job_name", "policy")}


@pytest.mark.parametrize("policy", ["act_state", "diffusion_state"])
def test_the_state_only_configs_read_the_task_state_and_no_camera(policy):
    from aerobench.envs.observations import TASK_STATE_DIM

    config = json.loads((CONFIGS / f"{policy}_tidy_house.json").read_text())["policy"]
    features = config["input_features"]
    assert features["observation.environment_state"] == {"type": "ENV", "shape": [TASK_STATE_DIM]}
    assert not any(k.startswith("observation.images.") for k in features)
    assert config["normalization_mapping"]["ENV"] in ("MEAN_STD", "MIN_MAX")  # LeRobot leaves ENV unnormalized
    # ACT reads the task state alone; LeRobot's Diffusion Policy always conditions on observation.state as well
    assert ("observation.state" in features) == (policy == "diffusion_state")


@pytest.mark.parametrize("policy", ["act", "diffusion", "act_cpu", "diffusion_cpu"])
def test_the_camera_configs_are_vision_tier_and_read_depth(policy):
    """The camera configs read the spec's VLA inputs and nothing privileged (`aerobench.tiers`), depth included: the
    spec-scale ones the three RGB-D cameras, the CPU variants the front and hand RGB and the hand camera's depth."""
    from aerobench import tiers

    features = json.loads((CONFIGS / f"{policy}_tidy_house.json").read_text())["policy"]["input_features"]
    assert tiers.tier_of(features) == "vision"
    depth = {k for k in features if k.startswith("observation.depth.")}
    assert depth == ({"observation.depth.drone_hand"} if policy.endswith("_cpu") else
                     {f"observation.depth.{c}" for c in ("drone_front", "drone_hand", "drone_own")})
