"""The `aerobench` LeRobot env type: config, adapter contract, and `lerobot-eval` running a tiny random ACT."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from lerobot.envs.configs import EnvConfig

from aerobench.envs.lerobot_env import AerobenchEnvConfig, EnvConfigError, make_lerobot_env

CAMERAS = ("drone_front", "drone_hand", "drone_own")


def test_registered_with_lerobot_and_features():
    assert EnvConfig.get_choice_class("aerobench") is AerobenchEnvConfig
    cfg = AerobenchEnvConfig(task="PrepareGroceries/open")
    assert cfg.features["action"].shape == (8,) and cfg.features["agent_pos"].shape == (25,)  # arm platform
    assert cfg.features_map["pixels/drone_hand"] == "observation.images.drone_hand"
    assert cfg.features_map["pixels/drone_hand_depth"] == "observation.depth.drone_hand"
    assert cfg.features_map["agent_pos"] == "observation.state"
    assert cfg.features_map["environment_state"] == "observation.environment_state"
    assert cfg.features["environment_state"].shape == (34,)  # the arm's task state
    with pytest.raises(EnvConfigError, match="unknown setting 'Mars'"):
        AerobenchEnvConfig(task="Mars/pick")
    with pytest.raises(EnvConfigError, match="TidyHouse has no close skill"):
        AerobenchEnvConfig(task="TidyHouse/close")


def test_adapter_speaks_lerobots_gym_contract():
    env = make_lerobot_env("TidyHouse/pick", episode_length=5)
    obs, info = env.reset(seed=0)
    assert set(obs["pixels"]) == set(CAMERAS) | {f"{c}_depth" for c in CAMERAS}
    for img in obs["pixels"].values():
        assert img.shape == (128, 128, 3) and img.dtype == np.uint8
    assert obs["agent_pos"].shape == (19,) and obs["agent_pos"].dtype == np.float32
    assert obs["environment_state"].shape == (31,) and obs["environment_state"].dtype == np.float32
    assert env.observation_space.contains(obs)
    assert env.task_description().startswith("pick up the ")
    assert env._max_episode_steps == 5
    obs, reward, terminated, truncated, info = env.step(np.zeros(5, dtype=np.float32))
    assert isinstance(reward, float) and isinstance(terminated, bool) and isinstance(info["is_success"], bool)
    env.close()


def _tiny_act(path: Path) -> None:
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.act.modeling_act import ACTPolicy
    from lerobot.policies.factory import make_pre_post_processors

    features = {f"observation.images.{c}": PolicyFeature(type=FeatureType.VISUAL, shape=(3, 128, 128)) for c in CAMERAS}
    features["observation.state"] = PolicyFeature(type=FeatureType.STATE, shape=(19,))
    cfg = ACTConfig(
        input_features=features,
        output_features={"action": PolicyFeature(type=FeatureType.ACTION, shape=(5,))},
        dim_model=32, n_heads=2, dim_feedforward=64, n_encoder_layers=1, n_decoder_layers=1,
        chunk_size=5, n_action_steps=5, pretrained_backbone_weights=None, use_vae=False, push_to_hub=False, device="cpu",
    )
    torch.manual_seed(0)
    ACTPolicy(cfg).save_pretrained(path)
    pre, post = make_pre_post_processors(cfg, dataset_stats=None)
    pre.save_pretrained(path)
    post.save_pretrained(path)


def test_lerobot_eval_runs_a_random_act_policy_offline(tmp_path):
    _tiny_act(tmp_path / "policy")
    lerobot_eval = shutil.which("lerobot-eval", path=os.path.dirname(sys.executable))
    env = dict(os.environ, HF_HUB_OFFLINE="1", MS_SKIP_ASSET_DOWNLOAD_PROMPT="1")
    result = subprocess.run(
        [
            lerobot_eval, f"--policy.path={tmp_path / 'policy'}", "--policy.device=cpu", "--env.type=aerobench",
            "--env.task=TidyHouse/pick", "--env.episode_length=6", "--eval.n_episodes=2", "--eval.batch_size=1",
            f"--output_dir={tmp_path / 'eval'}",
        ],
        capture_output=True, text=True, timeout=600, env=env,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    info = json.loads((tmp_path / "eval" / "eval_info.json").read_text())
    assert info["overall"]["n_episodes"] == 2


def test_create_envs_gives_lerobots_vector_env_contract():
    """Same-step autoreset as LeRobot's own envs, and `--env.episode_length` caps episodes (as lerobot-train's
    evaluation reads `_max_episode_steps`)."""
    vec = AerobenchEnvConfig(task="TidyHouse/pick", episode_length=2).create_envs(n_envs=1)["aerobench"][0]
    try:
        assert vec.metadata["autoreset_mode"] == gym.vector.AutoresetMode.SAME_STEP
        assert vec.call("_max_episode_steps")[0] == 2
        vec.reset(seed=0)
        zeros = np.zeros((1, 5), dtype=np.float32)
        _, _, terminated, truncated, _ = vec.step(zeros)
        assert not (terminated[0] or truncated[0])
        _, _, terminated, truncated, info = vec.step(zeros)
        assert truncated[0] or terminated[0]
        assert "final_obs" in info  # same-step autoreset hands back the last observation of the finished episode
    finally:
        vec.close()


def test_the_env_preprocessor_gives_depth_its_dataset_key():
    """LeRobot's eval loop names every pixel key observation.images.<key>; the env's preprocessor renames the packed
    depth to observation.depth.<camera>, the key the dataset (and a policy trained on it) uses."""
    from lerobot.envs.utils import preprocess_observation

    env = make_lerobot_env("TidyHouse/pick", episode_length=2)
    obs, _ = env.reset(seed=1)
    env.close()
    batch = {k: v[None] if isinstance(v, np.ndarray) else {c: x[None] for c, x in v.items()} for k, v in obs.items()}
    pre, _ = AerobenchEnvConfig(task="TidyHouse/pick").get_env_processors()
    out = pre(preprocess_observation(batch))
    assert {f"observation.depth.{c}" for c in CAMERAS} <= set(out) and "observation.images.drone_hand_depth" not in out
    assert {"observation.environment_state", "observation.state", "observation.images.drone_hand"} <= set(out)
    from aerobench.depth import decode_depth_mm

    assert decode_depth_mm(out["observation.depth.drone_hand"][0]).max() > 0  # real millimetres, decodable


def test_lerobot_eval_runs_a_committed_checkpoint_with_the_standard_flags_alone(tmp_path):
    """A committed LeRobot checkpoint that reads the task state runs under `lerobot-eval` with its standard flags:
    the env offers observation.environment_state (and depth) under the dataset's keys."""
    root = Path(__file__).resolve().parents[2]
    lerobot_eval = shutil.which("lerobot-eval", path=os.path.dirname(sys.executable))
    env = dict(os.environ, HF_HUB_OFFLINE="1", MS_SKIP_ASSET_DOWNLOAD_PROMPT="1")
    result = subprocess.run(
        [lerobot_eval, f"--policy.path={root / 'leaderboards/checkpoints/TidyHouse/act_state/place'}",
         "--env.type=aerobench", "--env.task=TidyHouse/place", "--env.episode_length=8", "--eval.n_episodes=1",
         "--eval.batch_size=1", "--policy.device=cpu", f"--output_dir={tmp_path / 'eval'}"],
        capture_output=True, text=True, timeout=900, env=env,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert "'n_episodes': 1" in result.stdout + result.stderr


def test_a_typo_in_the_task_ends_lerobots_traceback_with_aerobenchs_line(tmp_path):
    """draccus wraps a ValueError from a config into "Couldn't instantiate class ..."; aerobench's error is not one,
    so the last line a user sees is aerobench's."""
    lerobot_eval = shutil.which("lerobot-eval", path=os.path.dirname(sys.executable))
    env = dict(os.environ, HF_HUB_OFFLINE="1", MS_SKIP_ASSET_DOWNLOAD_PROMPT="1")
    result = subprocess.run([lerobot_eval, "--env.type=aerobench", "--env.task=TidyHous/pick", "--eval.n_episodes=1",
                             f"--output_dir={tmp_path}"], capture_output=True, text=True, timeout=300, env=env)
    last = result.stderr.strip().splitlines()[-1]
    assert result.returncode != 0 and "unknown setting 'TidyHous'; valid settings: TidyHouse" in last, last
    assert "Couldn't instantiate" not in result.stderr
