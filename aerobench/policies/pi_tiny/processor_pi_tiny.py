"""Processors of pi0 / pi0.5 with a local tokenizer folder instead of the hub's PaliGemma tokenizer.

LeRobot's `make_pi0_pre_post_processors` / `make_pi05_pre_post_processors` name `google/paligemma-3b-pt-224`, which
cannot load offline. `local_tokenizer` builds LeRobot's own pipelines (same steps, same order) with the tokenizer
step pointed at a folder; the saved `policy_preprocessor.json` then names that folder, so `lerobot-train` and
`aerobench eval` load it again from there.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

from lerobot.policies.pi0 import processor_pi0
from lerobot.policies.pi05 import processor_pi05
from lerobot.processor import TokenizerProcessorStep

from .configuration_pi_tiny import PI0TinyConfig, PI05TinyConfig

TOKENIZER_FILES = ("tokenizer.json", "tokenizer.model")


def check_tokenizer_folder(path: str | Path | None, what: str) -> Path:
    """A local tokenizer folder, or a one-line error saying what must be there."""
    if not path:
        raise ValueError(f"{what} needs a local tokenizer folder (tokenizer.json or tokenizer.model): build aerobench's "
                         f"with `aerobench pi-init --variant tiny`, or download the PaliGemma tokenizer")
    folder = Path(path).expanduser()
    if not folder.is_dir() or not any((folder / f).is_file() for f in TOKENIZER_FILES):
        raise ValueError(f"tokenizer folder {folder} for {what} must hold {' or '.join(TOKENIZER_FILES)} (plus "
                         f"tokenizer_config.json): the PaliGemma tokenizer, e.g. `hf download google/paligemma-3b-pt-224 "
                         f"--include 'tokenizer*' --local-dir {folder}` on a machine with internet (a gated model: "
                         f"accept its licence first), or aerobench's own from `aerobench pi-init --variant tiny`")
    return folder.resolve()


@contextmanager
def local_tokenizer(module: ModuleType, tokenizer: Path) -> Iterator[None]:
    """Within the block, the tokenizer step that `module` (a LeRobot pi processor module) builds loads `tokenizer`."""

    def step(**kwargs) -> TokenizerProcessorStep:
        return TokenizerProcessorStep(**{**kwargs, "tokenizer_name": str(tokenizer)})

    saved = module.TokenizerProcessorStep
    module.TokenizerProcessorStep = step
    try:
        yield
    finally:
        module.TokenizerProcessorStep = saved


def make_pi_processors(config, tokenizer: str | Path, dataset_stats=None):
    """LeRobot's pi0 or pi0.5 processors for `config` (its type decides which), tokenizing with a local folder."""
    module, factory = (
        (processor_pi05, processor_pi05.make_pi05_pre_post_processors)
        if config.type.startswith("pi05")
        else (processor_pi0, processor_pi0.make_pi0_pre_post_processors)
    )
    folder = check_tokenizer_folder(tokenizer, config.type)
    with local_tokenizer(module, folder):
        pre, post = factory(config, dataset_stats=dataset_stats)
    vocab_size = getattr(config, "vocab_size", None)  # the tiny variants' embedding size
    n_tokens = len(next(s for s in pre.steps if isinstance(s, TokenizerProcessorStep)).input_tokenizer)
    if vocab_size is not None and n_tokens > vocab_size:
        raise ValueError(f"tokenizer {folder} has {n_tokens} tokens but {config.type} embeds only {vocab_size}: "
                         f"set --policy.vocab_size {n_tokens} or use aerobench's tokenizer (aerobench pi-init)")
    return pre, post


def make_pi0_tiny_pre_post_processors(config: PI0TinyConfig, dataset_stats=None):
    return make_pi_processors(config, config.tokenizer_name, dataset_stats)


def make_pi05_tiny_pre_post_processors(config: PI05TinyConfig, dataset_stats=None):
    return make_pi_processors(config, config.tokenizer_name, dataset_stats)
