"""A tiny LeRobot ACT checkpoint written at test time: it reads the proprioceptive state and the front camera's RGB,
the inputs LeRobot's PolicyServer builds from a robot's observation (the committed ACT checkpoints read the privileged
task state, which that server drops). Random weights (seeded): the tests compare paths, not skill."""

from __future__ import annotations

from pathlib import Path

import torch

from aerobench.envs.observations import STATE_DIM
from aerobench.envs.platforms import PLATFORMS


def write_tiny_act(folder: Path, n_action_steps: int = 3, camera: str | None = "drone_front", seed: int = 0) -> Path:
    """A `pretrained_model` folder (config, weights, processors) for the gripper platform; returns it."""
    from lerobot.configs.types import FeatureType, NormalizationMode, PolicyFeature
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.act.modeling_act import ACTPolicy
    from lerobot.policies.factory import make_pre_post_processors

    action_dim = PLATFORMS["gripper"].action_dim
    inputs = {"observation.state": PolicyFeature(type=FeatureType.STATE, shape=(STATE_DIM,))}
    if camera:
        inputs[f"observation.images.{camera}"] = PolicyFeature(type=FeatureType.VISUAL, shape=(3, 128, 128))
    config = ACTConfig(
        input_features=inputs, output_features={"action": PolicyFeature(type=FeatureType.ACTION, shape=(action_dim,))},
        chunk_size=4, n_action_steps=n_action_steps, dim_model=32, n_heads=2, dim_feedforward=64, n_encoder_layers=1,
        n_decoder_layers=1, n_vae_encoder_layers=1, latent_dim=4, pretrained_backbone_weights=None, device="cpu",
        normalization_mapping={"VISUAL": NormalizationMode.MEAN_STD, "STATE": NormalizationMode.MEAN_STD,
                               "ACTION": NormalizationMode.MEAN_STD},
    )
    torch.manual_seed(seed)
    policy = ACTPolicy(config)
    stats = {"observation.state": {"mean": torch.zeros(STATE_DIM), "std": torch.ones(STATE_DIM)},
             "action": {"mean": torch.zeros(action_dim), "std": torch.full((action_dim,), 0.5)}}
    if camera:
        stats[f"observation.images.{camera}"] = {"mean": torch.full((3, 1, 1), 0.5), "std": torch.full((3, 1, 1), 0.25)}
    preprocess, postprocess = make_pre_post_processors(config, dataset_stats=stats)
    folder.mkdir(parents=True, exist_ok=True)
    policy.save_pretrained(folder)
    preprocess.save_pretrained(folder)
    postprocess.save_pretrained(folder)
    return folder
