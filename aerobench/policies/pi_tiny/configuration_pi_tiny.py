"""Configs of the tiny pi0 / pi0.5: LeRobot's configs plus the sizes LeRobot hard-codes, and a local tokenizer."""

from __future__ import annotations

from dataclasses import dataclass

from lerobot.configs import PreTrainedConfig
from lerobot.policies.pi0.configuration_pi0 import PI0Config
from lerobot.policies.pi05.configuration_pi05 import PI05Config

TINY_IMAGE_SIZE = 128  # aerobench's cameras render 128x128, so no resize is needed
GEMMA_NUM_HEADS = 8  # LeRobot 0.6.1's joint attention reshapes to 8 heads (pi0/pi05 `compute_layer_complete`)


@dataclass
class TinySizes:
    """Sizes of the shrunk PaliGemma (Gemma + SigLIP) and action expert. `paligemma_variant` and
    `action_expert_variant` are ignored: both Gemma stacks take these sizes (they attend jointly, layer by layer, so
    they must agree in depth and head size; LeRobot fixes 8 heads). `tokenizer_name` is a local tokenizer folder
    (`aerobench pi-init` writes one), used when processors are built from this config rather than loaded; its
    token ids must stay below `vocab_size`."""

    width: int = 64
    depth: int = 2
    mlp_dim: int = 128
    num_kv_heads: int = 1
    head_dim: int = 16  # x 8 heads: queries are 128 wide
    vision_width: int = 64
    vision_depth: int = 2
    vision_mlp_dim: int = 128
    vision_num_heads: int = 2
    vision_patch_size: int = 16
    vocab_size: int = 1024  # PaliGemma's 257152 would be 3 x 16M unused parameters at width 64; must cover the tokenizer
    tokenizer_name: str | None = None

    def validate_sizes(self) -> None:
        if min(self.width, self.depth, self.mlp_dim, self.num_kv_heads, self.head_dim, self.vocab_size) <= 0:
            raise ValueError(f"{self.type}: width, depth, mlp_dim, num_kv_heads, head_dim and vocab_size must be > 0")
        if GEMMA_NUM_HEADS % self.num_kv_heads:
            raise ValueError(f"{self.type}: num_kv_heads ({self.num_kv_heads}) must divide the {GEMMA_NUM_HEADS} "
                             f"attention heads LeRobot's pi models use")
        if self.vision_width % self.vision_num_heads:
            raise ValueError(f"{self.type}: vision_width ({self.vision_width}) must be a multiple of "
                             f"vision_num_heads ({self.vision_num_heads})")
        if self.image_resolution[0] % self.vision_patch_size:
            raise ValueError(f"{self.type}: image_resolution {tuple(self.image_resolution)} must be a multiple of "
                             f"vision_patch_size ({self.vision_patch_size})")


@PreTrainedConfig.register_subclass("pi0_tiny")
@dataclass
class PI0TinyConfig(PI0Config, TinySizes):
    image_resolution: tuple[int, int] = (TINY_IMAGE_SIZE, TINY_IMAGE_SIZE)

    def __post_init__(self):
        super().__post_init__()
        self.validate_sizes()


@PreTrainedConfig.register_subclass("pi05_tiny")
@dataclass
class PI05TinyConfig(PI05Config, TinySizes):
    image_resolution: tuple[int, int] = (TINY_IMAGE_SIZE, TINY_IMAGE_SIZE)
    tokenizer_max_length: int = 64  # "Task: <instruction>, State: <19 or 25 bins>;\nAction: " fits in about 45 tokens

    def __post_init__(self):
        super().__post_init__()
        self.validate_sizes()
