"""The dataset card: `README.md` at the root of every merged aerobench dataset, as LeRobot's hub datasets have.

It says what generated the data (the `aerobench generate` command, rebuilt from `.aerobench/generation.json`), the
platform, setting, skills and objects, the episodes' outcomes and modes, the features, and how to load and train on
it. Written after each merge, so it always describes the merged episodes.
"""

from __future__ import annotations

import re
from pathlib import Path

from .. import __version__
from .features import FPS, VIDEO_BACKEND
from .info import dataset_info
from .layout import input_tiers, read_generation_spec

CARD_FILE = "README.md"


def generate_command(spec: dict, out: str | Path) -> str:
    """The `aerobench generate` command line that wrote a dataset, rebuilt from its generation spec."""
    parts = ["aerobench generate", f"--setting {spec['setting']}", f"--skills {','.join(spec['skills'])}"]
    for key in ("episodes", "seed", "keep", "policy", "controller"):  # a hand-written spec may leave some out
        if spec.get(key) is not None:
            parts.append(f"--{key} {spec[key]}")
    if spec.get("objects"):
        parts.append(f"--objects {','.join(spec['objects'])}")
    if spec.get("platform"):
        parts.append(f"--platform {spec['platform']}")
    if not spec.get("record_cameras", True):
        parts.append("--no-cameras")
    for key, option in (("checkpoint", "checkpoint"), ("labeler", "label-with"), ("action_noise", "action-noise")):
        if spec.get(key):
            parts.append(f"--{option} {spec[key]}")
    return " ".join([*parts, f"--out {out}"])


def _table(title: str, counts: dict[str, int]) -> list[str]:
    lines = [f"| {title} | episodes |", "| --- | --- |"]
    return lines + [f"| {value or '-'} | {n} |" for value, n in counts.items()]


def dataset_card(root: str | Path) -> str:
    """The card's Markdown for the dataset at `root`."""
    root = Path(root)
    spec, info = read_generation_spec(root), dataset_info(root)
    spec = {k: "not recorded" for k in ("keep", "policy", "controller", "seed")} | {
        k: v for k, v in spec.items() if v is not None}
    counts = info["counts"]
    platform = spec.get("platform") or (info["robot_type"] or "").removeprefix("aerobench_") or "per skill"
    cameras = "three 128x128 RGB-D cameras" if spec.get("record_cameras", True) else "state only (no cameras)"
    name = root.name
    objects = ", ".join(spec["objects"]) if spec.get("objects") else "all of the setting's, in turn"
    if not any(counts["object"]):
        objects = "none (the skills act on no object)"
    config = ("act_state_" if not spec.get("record_cameras", True) else "act_") + \
        re.sub(r"(?<!^)(?=[A-Z])", "_", spec["setting"]).lower()
    lines = [
        "---",
        "task_categories:",
        "- robotics",
        "tags:",
        "- LeRobot",
        "- aerobench",
        f"- {spec['setting']}",
        "configs:",
        "- config_name: default",
        "  data_files: data/*/*.parquet",
        "---",
        "",
        f"# aerobench {spec['setting']}: {', '.join(spec['skills'])}",
        "",
        f"Aerial manipulation demonstrations from aerobench {__version__} (LeRobotDataset v3): a quadrotor with a "
        f"{platform} platform, {cameras}, {FPS} frames per second, annotated with the spec's events, phases and "
        f"outcome modes.",
        "",
        "Generated with:",
        "",
        "```bash",
        generate_command(spec, root),
        "```",
        "",
        "| | |",
        "| --- | --- |",
        f"| setting | {spec['setting']} |",
        f"| skills | {', '.join(spec['skills'])} |",
        f"| objects | {objects} |",
        f"| policy | {spec['policy']} ({spec['controller']} flight controller) |",
        f"| platform | {platform} |",
        f"| episodes kept | {spec['keep']} ({info['episodes']} of {info['processed']} generated) |",
        f"| frames | {info['frames']} at {FPS} fps |",
        f"| seed | {spec['seed']} (episode i: seed x 1000003 + i) |",
        "",
        "## Episodes",
        "",
        *_table("outcome", counts["outcome"]), "",
        *_table("mode", counts["mode"]), "",
        *_table("skill", counts["skill"]), "",
        *_table("object", counts["object"]), "",
        "## Features",
        "",
        "| feature | dtype | shape |",
        "| --- | --- | --- |",
        *[f"| `{key}` | {ft['dtype']} | {'x'.join(str(n) for n in ft['shape'])} |" for key, ft in info["features"].items()],
        "",
        "Depth is packed losslessly into RGB images (uint16 millimetres, R high byte, G low byte, B a linear 20 mm "
        "copy for CNNs); every column, the per-episode annotations (`meta/aerobench_episodes.jsonl`) and "
        "`meta/aerobench.json` are documented in aerobench's docs/datasets.md.",
        "",
        "Input tiers (what a policy trained on this dataset may read; aerobench's docs/evaluation.md):",
        "",
        *[f"- `{name}`: {', '.join(f'`{k}`' for k in keys)}" for name, keys in input_tiers(info["features"]).items()],
        "",
        "## Load and train",
        "",
        "```python",
        "from lerobot.datasets.lerobot_dataset import LeRobotDataset",
        "",
        f'ds = LeRobotDataset("local/{name}", root="{root}", video_backend="{VIDEO_BACKEND}")',
        "```",
        "",
        "```bash",
        f"aerobench dataset info {root}",
        f"aerobench train bc --dataset {root} --out runs/bc_{name}",
        *([f"aerobench train bc --dataset {root} --inputs vision --images --out runs/bc_vision_{name}"]
          if spec.get("record_cameras", True) else []),
        f"lerobot-train --config_path configs/{config}.json --dataset.root {root} "
        f"--dataset.repo_id local/{name}",
        "```",
        "",
    ]
    return "\n".join(lines)


def write_dataset_card(root: str | Path) -> Path:
    path = Path(root) / CARD_FILE
    tmp = path.with_suffix(".tmp")
    tmp.write_text(dataset_card(root))
    tmp.replace(path)
    return path
