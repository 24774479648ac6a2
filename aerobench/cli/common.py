"""What every `aerobench` command shares: the one-line error parser, the user-error type and small argument types."""

from __future__ import annotations

import argparse
import json
import math
import os


def quiet_offline_environment() -> None:
    """Offline by default, nothing waits on a download prompt, and the libraries' start-up noise stays quiet."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    os.environ.setdefault("MS_SKIP_ASSET_DOWNLOAD_PROMPT", "1")
    from ..quiet import quiet_libraries

    quiet_libraries()


class Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, no usage dump
        self.exit(2, f"{self.prog}: error: {message}\n")


class UserError(Exception):
    """A mistake in the user's input: reported in one line."""


def print_metrics(metrics: dict, as_json: bool) -> None:
    width = max(len(k) for k in metrics)
    for key, value in metrics.items():
        shown = f"{value:.6g}" if isinstance(value, float) else str(value)
        print(f"{key:<{width}}  {shown}")
    if as_json:
        clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in metrics.items()}
        print(json.dumps(clean))


def parse_shard(text: str) -> tuple[int, int]:
    try:
        i, k = (int(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--shard must look like 0/4, got {text!r}") from None
    return i, k


def parse_csv(text: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in text.split(",") if v.strip())


def add_ray_options(p, shards_name: str | None = None) -> None:
    p.add_argument("--ray", nargs="?", const="local", default=None, metavar="ADDRESS",
                   help="run the shards as Ray tasks: alone, a local Ray runtime on this machine's cores; with HOST:PORT "
                        "(or auto), the cluster there (ray start --head); the output folder must be shared by the workers")
    if shards_name:
        p.add_argument(f"--{shards_name}", type=int, default=None,
                       help="with --ray: how many shards (default: one per CPU of the Ray runtime; with --sim-backend "
                            "physx_cuda one per GPU, each shard given its own)")

