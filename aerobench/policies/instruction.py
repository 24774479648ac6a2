"""The language instruction as a small policy reads it: a bag of hashed words.

aerobench's instructions come from templates ("pick up the sugar box from the side counter", "place the bowl on the
marked spot of the dining table"), so which words appear is what matters (the object to pick among distractors, the
support). Each lower-cased word is hashed (CRC-32, stable across processes, unlike Python's `hash`) into one of
`BUCKETS` ids; the network averages a learned embedding of the ids (`torch.nn.EmbeddingBag`). No vocabulary is
stored, so a checkpoint reads any instruction; two words that share a bucket share an embedding.
"""

from __future__ import annotations

import re
import zlib

import torch

BUCKETS = 4096  # id 0 is padding
MAX_WORDS = 32
_WORD = re.compile(r"[a-z0-9]+")


def word_ids(text: str) -> list[int]:
    return [1 + zlib.crc32(w.encode()) % (BUCKETS - 1) for w in _WORD.findall(text.lower())][:MAX_WORDS]


def instruction_tokens(texts: list[str]) -> torch.Tensor:
    """`(N, MAX_WORDS)` word ids of each instruction, 0-padded."""
    out = torch.zeros(len(texts), MAX_WORDS, dtype=torch.long)
    for i, text in enumerate(texts):
        ids = word_ids(text)
        out[i, : len(ids)] = torch.tensor(ids, dtype=torch.long)
    return out


def named_phrase(tokens: torch.Tensor, phrases: list[str]) -> torch.Tensor:
    """`(N,)` which of `phrases` each instruction `(N, W)` (word ids) names: the longest one all of whose words it
    holds ("tomato soup can" over "can"), -1 where none."""
    out = torch.full((len(tokens),), -1, dtype=torch.long, device=tokens.device)
    longest = torch.zeros(len(tokens), dtype=torch.long, device=tokens.device)
    for i, phrase in enumerate(phrases):
        ids = torch.tensor(word_ids(phrase), dtype=torch.long, device=tokens.device)
        named = (tokens[:, :, None] == ids).any(1).all(-1) & (len(ids) > longest)
        out = torch.where(named, i, out)
        longest = torch.where(named, len(ids), longest)
    return out
