"""The tiny pi0 / pi0.5 policies: LeRobot's `PI0Policy` / `PI05Policy`, built at the sizes of a `TinySizes` config.

LeRobot builds the model from hard-coded sizes: `get_gemma_config(variant)`, a SigLIP So400m vision tower whose
projection is fixed at 2048 wide, and PaliGemma's 257152-token vocabulary. While, and only while, a tiny policy's
`__init__` runs, the size table and the two model classes LeRobot instantiates in its modeling module are swapped
for ones that apply the tiny sizes; everything else (layers, attention, flow matching,
`from_pretrained`, `select_action`) is LeRobot's unmodified code. Other users of the module never see the swap.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

from lerobot.policies.pi0 import modeling_pi0
from lerobot.policies.pi05 import modeling_pi05

from .configuration_pi_tiny import GEMMA_NUM_HEADS, PI0TinyConfig, PI05TinyConfig, TinySizes


@contextmanager
def tiny_sizes(module: ModuleType, sizes: TinySizes) -> Iterator[None]:
    """Within the block, `module` (LeRobot's modeling_pi0 or modeling_pi05) builds a model of `sizes`."""
    gemma = module.GemmaConfig(width=sizes.width, depth=sizes.depth, mlp_dim=sizes.mlp_dim,
                               num_heads=GEMMA_NUM_HEADS, num_kv_heads=sizes.num_kv_heads, head_dim=sizes.head_dim)
    paligemma_cls, expert_cls = module.PaliGemmaForConditionalGenerationWithPiGemma, module.PiGemmaForCausalLM

    def paligemma(*, config):  # LeRobot calls it with config=; the tiny sizes are `sizes`
        config.text_config.vocab_size = sizes.vocab_size
        vision = config.vision_config
        vision.hidden_size = sizes.vision_width
        vision.num_hidden_layers = sizes.vision_depth
        vision.intermediate_size = sizes.vision_mlp_dim
        vision.num_attention_heads = sizes.vision_num_heads
        vision.patch_size = sizes.vision_patch_size
        vision.projection_dim = config.text_config.hidden_size  # image tokens enter the Gemma stack
        return paligemma_cls(config=config)

    def expert(*, config):
        config.vocab_size = sizes.vocab_size
        return expert_cls(config=config)

    swaps = {"get_gemma_config": lambda variant: gemma, "PaliGemmaForConditionalGenerationWithPiGemma": paligemma,
             "PiGemmaForCausalLM": expert}
    saved = {name: getattr(module, name) for name in swaps}
    for name, value in swaps.items():
        setattr(module, name, value)
    try:
        yield
    finally:
        for name, value in saved.items():
            setattr(module, name, value)


class PI0TinyPolicy(modeling_pi0.PI0Policy):
    """LeRobot's pi0 at the sizes of a `PI0TinyConfig`."""

    config_class = PI0TinyConfig
    name = "pi0_tiny"

    def __init__(self, config: PI0TinyConfig, **kwargs):
        with tiny_sizes(modeling_pi0, config):
            super().__init__(config, **kwargs)


class PI05TinyPolicy(modeling_pi05.PI05Policy):
    """LeRobot's pi0.5 at the sizes of a `PI05TinyConfig`."""

    config_class = PI05TinyConfig
    name = "pi05_tiny"

    def __init__(self, config: PI05TinyConfig, **kwargs):
        with tiny_sizes(modeling_pi05, config):
            super().__init__(config, **kwargs)
