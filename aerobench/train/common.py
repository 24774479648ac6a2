"""What `bc.py` and `ppo.py` share: seeding, scalar logging, resume checks, and CLI flags made from a config dataclass."""

from __future__ import annotations

import argparse
import dataclasses
import json
import random
import types
import typing
from pathlib import Path

import numpy as np
import torch

from ..policies.learned import TRAIN_STATE_FILE

SCALARS_FILE = "scalars.jsonl"


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def config_dict(config) -> dict:
    """A config dataclass as JSON-ready values (tuples -> lists, paths -> str)."""
    return json.loads(json.dumps(dataclasses.asdict(config), default=str))


def check_resumable(saved: dict, current: dict, out: Path, ignore: tuple[str, ...]) -> None:
    """A resumed run must have been started with the same config (apart from the budget and `ignore`)."""
    differ = sorted(k for k in set(saved) | set(current) if k not in ignore and saved.get(k) != current.get(k))
    if differ:
        raise ValueError(f"{out} holds a run with a different config ({', '.join(differ)} differ); "
                         f"use the same options to resume, or choose another --out")


def load_train_state(checkpoint: Path, out: Path) -> dict:
    """The resume state of a run's checkpoint; a checkpoint without one (copied for evaluation only) cannot resume."""
    path = checkpoint / TRAIN_STATE_FILE
    if not path.is_file():
        raise ValueError(f"{checkpoint} has no train_state.pt, so the run in {out} cannot be resumed; choose another --out")
    return torch.load(path, weights_only=False)


def truncate_jsonl(path: Path, key: str, upto: int) -> list[dict]:
    """Drop rows with `row[key] > upto`: what an interrupted run logged after its last checkpoint is redone. Returns
    the rows kept."""
    if not path.exists():
        return []
    lines = [line for line in path.read_text().splitlines() if line.strip()]
    rows = [json.loads(line) for line in lines]
    kept = [(line, row) for line, row in zip(lines, rows) if row[key] <= upto]
    if len(kept) != len(rows):
        path.write_text("".join(line + "\n" for line, _ in kept))
    return [row for _, row in kept]


class ScalarLog:
    """TensorBoard-style scalars: always `OUT/scalars.jsonl` (one `{"step", "tag", "value"}` per line); also a
    TensorBoard event file when `tensorboard` is installed. A resumed run drops what came after its checkpoint."""

    def __init__(self, out: Path, resume_step: int):
        out.mkdir(parents=True, exist_ok=True)
        self.path = out / SCALARS_FILE
        truncate_jsonl(self.path, "step", resume_step)
        self.file = open(self.path, "a")
        self.tb = None
        try:
            from torch.utils.tensorboard import SummaryWriter

            self.tb = SummaryWriter(str(out / "tensorboard"), purge_step=resume_step + 1 if resume_step else None)
        except ImportError:  # tensorboard is not a dependency; the JSONL holds the same scalars
            pass

    def add(self, tag: str, value: float, step: int) -> None:
        self.file.write(json.dumps({"step": int(step), "tag": tag, "value": float(value)}) + "\n")
        if self.tb is not None:
            self.tb.add_scalar(tag, float(value), int(step))

    def flush(self) -> None:
        self.file.flush()
        if self.tb is not None:
            self.tb.flush()

    def close(self) -> None:
        self.file.close()
        if self.tb is not None:
            self.tb.close()


def read_scalars(out: Path, tag: str) -> list[tuple[int, float]]:
    """`(step, value)` of one tag from a run's scalars.jsonl (a running run's torn last line is ignored)."""
    from ..rollout.records import read_records

    path = Path(out) / SCALARS_FILE
    return [(r["step"], r["value"]) for r in (read_records(path) if path.exists() else []) if r["tag"] == tag]


# ── CLI flags from a config dataclass ─────────────────────────────────────────────────────────────────────────────


def _csv(text: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in text.split(",") if v.strip())


def _ints(text: str) -> tuple[int, ...]:
    return tuple(int(v) for v in _csv(text))


def add_config_arguments(parser: argparse.ArgumentParser, cls, required: tuple[str, ...] = ()) -> None:
    """One `--flag-name` per field of `cls` (a dataclass); help text from the field's `metadata["help"]`."""
    hints = typing.get_type_hints(cls)
    for field in dataclasses.fields(cls):
        flag = "--" + field.name.replace("_", "-")
        kind = hints[field.name]
        args = typing.get_args(kind)
        if isinstance(kind, types.UnionType) or typing.get_origin(kind) is typing.Union:
            kind = next(a for a in args if a is not type(None))  # X | None: the flag gives X
            args = typing.get_args(kind)
        default = None if field.default is dataclasses.MISSING else field.default
        help_text = field.metadata.get("help", "")
        if field.name not in required and default is not None:
            shown = (",".join(map(str, default)) or "none") if isinstance(default, tuple) else default
            help_text += f" (default: {shown})"
        options: dict = {"dest": field.name, "help": help_text.strip(), "default": default}
        if field.name in required:
            options.update(required=True, default=None)
        if "const" in field.metadata:  # a flag that may stand alone (`--ray`) or take a value (`--ray HOST:PORT`)
            options.update(nargs="?", const=field.metadata["const"])
        if kind is bool:
            options["action"] = argparse.BooleanOptionalAction
        elif typing.get_origin(kind) is tuple:
            options["type"] = _ints if args and args[0] is int else _csv
        else:
            options["type"] = kind
        parser.add_argument(flag, **options)


def config_from_args(cls, args: argparse.Namespace):
    return cls(**{f.name: getattr(args, f.name) for f in dataclasses.fields(cls)})
