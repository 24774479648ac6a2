"""`aerobench pi-init`: a LeRobot `pretrained_model` folder for pi0 / pi0.5 that `lerobot-train --policy.path` fine-tunes.

Two sources, one output layout (config.json, model.safetensors, policy_preprocessor.json, policy_postprocessor.json
and their normalization stats), with input features and stats taken from an exported aerobench dataset:

- pretrained: the user's local LeRobot pi0 / pi0.5 weights (`--weights DIR`, e.g. a download of `lerobot/pi05_base`)
  and local PaliGemma tokenizer (`--tokenizer DIR`). The weights file is linked, not copied; the processors are
  LeRobot's own with the tokenizer step pointed at the local folder, so nothing is fetched from the hub later.
- tiny: a randomly initialised `pi0_tiny` / `pi05_tiny` (aerobench.policies.pi_tiny) with aerobench's offline
  tokenizer written beside it (`OUT/tokenizer`), small enough to train and evaluate on a CPU in tests.

The folder's tokenizer path is absolute: checkpoints that lerobot-train writes from it keep loading that tokenizer.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

PI_POLICIES = ("pi0", "pi05")
VARIANTS = ("pretrained", "tiny")
WEIGHT_FILES = ("config.json", "model.safetensors")


@dataclass(frozen=True)
class PiInitConfig:
    policy: str
    dataset: str
    out: str
    variant: str = "pretrained"
    weights: str | None = None
    tokenizer: str | None = None
    seed: int = 0

    def validate(self) -> None:
        if self.policy not in PI_POLICIES:
            raise ValueError(f"unknown pi policy {self.policy!r}; valid: {', '.join(PI_POLICIES)}")
        if self.variant not in VARIANTS:
            raise ValueError(f"unknown variant {self.variant!r}; valid: {', '.join(VARIANTS)}")
        if self.variant == "tiny" and (self.weights or self.tokenizer):
            raise ValueError("--variant tiny is randomly initialised with aerobench's own tokenizer; drop --weights "
                             "and --tokenizer (or use --variant pretrained)")
        if self.variant == "pretrained" and not self.weights:
            raise ValueError(f"--variant pretrained needs --weights DIR (your local LeRobot {self.policy} checkpoint: "
                             f"{' + '.join(WEIGHT_FILES)}, e.g. lerobot/{self.policy}_base) and --tokenizer DIR (the "
                             f"PaliGemma tokenizer); or use --variant tiny for a small random model")
        out = Path(self.out)
        if out.exists() and any(out.iterdir()):
            raise ValueError(f"--out {out} is not empty; pick a new folder (nothing is overwritten)")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--policy", required=True, help="pi0 or pi05")
    p.add_argument("--dataset", required=True, help="an exported aerobench dataset (input features and normalization)")
    p.add_argument("--out", required=True, help="new folder to write (pass it to lerobot-train as --policy.path)")
    p.add_argument("--variant", default="pretrained",
                   help="pretrained (your local weights, --weights and --tokenizer) or tiny (random, CPU-sized)")
    p.add_argument("--weights", default=None, help="local LeRobot pi0/pi05 checkpoint folder (config.json, model.safetensors)")
    p.add_argument("--tokenizer", default=None, help="local PaliGemma tokenizer folder (tokenizer.json or tokenizer.model)")
    p.add_argument("--seed", type=int, default=0, help="seed of the tiny variant's random weights")


def dataset_features(root: Path) -> tuple[dict, dict]:
    """Policy input features (state and RGB cameras; depth is left out, as in the ACT config) and the action feature."""
    from lerobot.configs.types import FeatureType, PolicyFeature

    info_path = root / "meta" / "info.json"
    if not info_path.is_file():
        raise ValueError(f"--dataset {root} is not a LeRobot dataset (no meta/info.json); export one with "
                         f"`aerobench generate --out {root} ...`")
    features = json.loads(info_path.read_text())["features"]
    if "observation.state" not in features or "action" not in features:
        raise ValueError(f"dataset {root} lacks observation.state or action; export it with `aerobench generate`")
    inputs = {"observation.state": PolicyFeature(type=FeatureType.STATE, shape=tuple(features["observation.state"]["shape"]))}
    for key, ft in features.items():
        if key.startswith("observation.images.") and ft["dtype"] in ("video", "image"):
            h, w, c = ft["shape"]  # the dataset stores HWC; policies take CHW
            inputs[key] = PolicyFeature(type=FeatureType.VISUAL, shape=(c, h, w))
    if len(inputs) == 1:
        raise ValueError(f"dataset {root} has no camera images; pi0/pi0.5 need them (export without --no-cameras)")
    outputs = {"action": PolicyFeature(type=FeatureType.ACTION, shape=tuple(features["action"]["shape"]))}
    return inputs, outputs


def dataset_stats(root: Path) -> dict:
    from lerobot.datasets import LeRobotDatasetMetadata

    return LeRobotDatasetMetadata(f"local/{root.name}", root=root).stats


def check_weights_folder(path: str | Path, policy: str) -> Path:
    folder = Path(path).expanduser()
    missing = [f for f in WEIGHT_FILES if not (folder / f).is_file()]
    if missing:
        raise ValueError(f"weights folder {folder} lacks {', '.join(missing)}: put LeRobot's {policy} checkpoint there "
                         f"({' + '.join(WEIGHT_FILES)}), e.g. `hf download lerobot/{policy}_base --local-dir {folder}` "
                         f"on a machine with internet")
    return folder.resolve()


def init_pi(config: PiInitConfig) -> Path:
    """Write the `pretrained_model` folder described in the module docstring; returns it."""
    config.validate()
    import torch
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    from .pi_tiny import PI0TinyConfig, PI05TinyConfig
    from .pi_tiny.processor_pi_tiny import check_tokenizer_folder, make_pi_processors
    from .pi_tokenizer import save_tokenizer

    if config.variant == "pretrained":  # the user's paths first: the most likely mistake, and the cheapest check
        weights = check_weights_folder(config.weights, config.policy)
        tokenizer = check_tokenizer_folder(config.tokenizer, f"--policy {config.policy}")
        policy_cfg = PreTrainedConfig.from_pretrained(weights, local_files_only=True)
        if policy_cfg.type not in (config.policy, f"{config.policy}_tiny"):  # a tiny folder works too (tests)
            raise ValueError(f"weights folder {weights} holds a {policy_cfg.type!r} checkpoint, not {config.policy!r}; "
                             f"use --policy {policy_cfg.type.removesuffix('_tiny')}")
    root = Path(config.dataset).expanduser()
    inputs, outputs = dataset_features(root)
    stats = dataset_stats(root)
    out = Path(config.out).expanduser().resolve()
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        if config.variant == "tiny":
            tokenizer = save_tokenizer(out / "tokenizer")
            cls = PI05TinyConfig if config.policy == "pi05" else PI0TinyConfig
            policy_cfg = cls(input_features=inputs, output_features=outputs, tokenizer_name=str(tokenizer),
                             device="cpu", push_to_hub=False)
            torch.manual_seed(config.seed)
            get_policy_class(policy_cfg.type)(policy_cfg).save_pretrained(out)
            pre, post = make_pre_post_processors(policy_cfg, dataset_stats=stats)
        else:
            policy_cfg.input_features, policy_cfg.output_features = inputs, outputs
            policy_cfg.save_pretrained(out)
            os.symlink(weights / "model.safetensors", out / "model.safetensors")  # a pi0.5 checkpoint is several GB
            pre, post = make_pi_processors(policy_cfg, tokenizer, dataset_stats=stats)
        pre.save_pretrained(out)
        post.save_pretrained(out)
    except BaseException:
        if created:  # no half-written folder is left behind to block the next attempt
            shutil.rmtree(out, ignore_errors=True)
        raise
    return out
