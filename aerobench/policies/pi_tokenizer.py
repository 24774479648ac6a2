"""An offline tokenizer for the tiny pi0 / pi0.5 variants: a WordPiece vocabulary built from aerobench's own words.

LeRobot's pi0 / pi0.5 processors tokenize the instruction (pi0.5 also the discretized state) with the PaliGemma
tokenizer from the hub, which is gated and unreachable offline. The tiny variants only need *a* tokenizer that
LeRobot's `TokenizerProcessorStep` can load by folder (`AutoTokenizer.from_pretrained(DIR)`) and that pads to a fixed
length on the right. This one is built in code, with no download and no training: whole words for everything
aerobench says (skills, objects, fixtures, scene phrases, pi0.5's prompt words and state bins) and single characters (plus their
`##` continuations) so that any ASCII text still encodes without `<unk>`. Like PaliGemma's, it starts every
sequence with `<bos>` and pads with id 0. The same code always gives the same vocabulary and ids.
"""

from __future__ import annotations

import string
from pathlib import Path

from ..envs.objects import ALL_OBJECTS
from ..envs.tasks import FIXTURE_PHRASES, SETTINGS, SKILLS, object_phrase

SPECIAL_TOKENS = ("<pad>", "<eos>", "<bos>", "<unk>")  # PaliGemma's order: pad 0, eos 1, bos 2, unk 3
# Words of the scene phrases instructions use (supports, nav points, rooms: aerobench/envs/scenes) and of the
# instruction templates (aerobench/envs/tasks.py); words missing here still encode, as characters.
SCENE_WORDS = (
    "the", "up", "from", "on", "to", "fly", "then", "of", "by", "a", "kitchen", "counter", "table", "shelf", "cabinet",
    "top", "bottom", "middle", "low", "side", "short", "island", "drawer", "refrigerator", "fridge", "door", "doorway",
    "room", "dining", "living", "bedroom", "bathroom", "office", "hallway", "lobby", "street", "building", "entrance",
    "vehicle", "pickup", "cargo", "bed", "bench", "sofa", "coffee", "tv", "bookshelf", "sideboard", "dresser",
    "bedside", "desk", "filing", "s", "package",
)
PROMPT_WORDS = ("task", "state", "action")  # pi0.5's prompt: "Task: ..., State: 12 200 ...;\nAction: "
STATE_BINS = 256  # pi0.5 writes each normalized state value as its bin, 0..255 (lerobot/policies/pi05/processor_pi05.py)


def vocabulary() -> list[str]:
    """Token strings in id order: special tokens, characters, `##` continuations, then whole words."""
    words: list[str] = [*SKILLS, "pick", "place", "open", "close", "fly"]
    words += [w for name in ALL_OBJECTS for w in object_phrase(name).split()]
    words += [w for phrase in FIXTURE_PHRASES.values() for w in phrase.split()]
    words += [w.lower() for s in SETTINGS.values() for w in s.description.replace(",", " ").replace(":", " ").split()]
    words += [*SCENE_WORDS, *PROMPT_WORDS, *(str(i) for i in range(STATE_BINS))]
    chars = [c for c in string.printable if not c.isspace()]
    vocab = [*SPECIAL_TOKENS, *chars, *(f"##{c}" for c in chars)]
    seen = set(vocab)
    for word in words:
        if word not in seen and word.isascii():
            vocab.append(word)
            seen.add(word)
    return vocab


def build_tokenizer():
    """The tokenizer as a `transformers` fast tokenizer (lower-cases, splits on whitespace and punctuation)."""
    from tokenizers import Tokenizer, decoders, normalizers, pre_tokenizers, processors
    from tokenizers.models import WordPiece
    from transformers import PreTrainedTokenizerFast

    vocab = {token: i for i, token in enumerate(vocabulary())}
    core = Tokenizer(WordPiece(vocab, unk_token="<unk>", max_input_chars_per_word=100))
    core.normalizer = normalizers.Sequence([normalizers.NFKC(), normalizers.Lowercase()])
    core.pre_tokenizer = pre_tokenizers.Whitespace()
    core.decoder = decoders.WordPiece()
    core.post_processor = processors.TemplateProcessing(
        single="<bos> $A", pair="<bos> $A $B", special_tokens=[("<bos>", vocab["<bos>"])]
    )
    return PreTrainedTokenizerFast(
        tokenizer_object=core, pad_token="<pad>", eos_token="<eos>", bos_token="<bos>", unk_token="<unk>",
        padding_side="right", model_max_length=512,
    )


def save_tokenizer(out: str | Path) -> Path:
    """Write the tokenizer folder (`tokenizer.json`, `tokenizer_config.json`, ...) that `AutoTokenizer` loads."""
    out = Path(out)
    build_tokenizer().save_pretrained(out)
    return out
