"""Which evaluation starts a learned policy already saw in training.

`aerobench generate` and `aerobench eval` share the rollout runner's seeded plan, so an evaluation with the seed its
training data was generated with replays the demonstrations' own starts (same setting, skill, object and env seed).
This module traces a checkpoint back to what it trained on (the exported dataset a BC or LeRobot checkpoint names;
the env episodes of a PPO run and of the BC run it started from) and counts the evaluation episodes among them, so
results say whether they are held out.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from ..envs.tasks import get_setting
from ..rollout.chained import split_checkpoints
from ..rollout.runner import EpisodePlan

# An episode start: (setting, skill, object, env seed); object None matches any object (RL resets cycle objects).
Start = tuple[str, str, "str | None", int]


@dataclass
class TrainingStarts:
    starts: set[Start] = field(default_factory=set)
    sources: list[str] = field(default_factory=list)  # datasets / RL runs the starts come from
    untraced: list[str] = field(default_factory=list)  # checkpoints whose training data could not be found

    def add(self, other: TrainingStarts) -> None:
        self.starts |= other.starts
        self.sources += [s for s in other.sources if s not in self.sources]
        self.untraced += [s for s in other.untraced if s not in self.untraced]

    def seen(self, setting: str, skill: str, obj: str | None, seed: int) -> bool:
        return (setting, skill, obj, seed) in self.starts or (setting, skill, None, seed) in self.starts


def dataset_starts(root: Path) -> TrainingStarts:
    """Every episode start recorded in an exported dataset's annotations (all outcomes: a LeRobot policy trains on
    every episode, BC on the successful ones; counting all of them is the safe side)."""
    path = root / "meta" / "aerobench_episodes.jsonl"
    if not path.is_file():
        return TrainingStarts(untraced=[str(root)])
    starts = set()
    for line in path.read_text().splitlines():
        r = json.loads(line)
        starts.add((r["setting"], r["skill"], r.get("object"), int(r["seed"])))
    return TrainingStarts(starts, sources=[str(root)])


def _recorded_path(path: str | None, run_dir: Path, recorded_run_dir: str | None) -> Path | None:
    """A path a training run recorded as it was given: absolute, or relative to the directory the run was started
    in, which is `run_dir` less its recorded (relative) name. None when it is not there any more."""
    if not path:
        return None
    candidates, run_dir = [Path(path)], run_dir.resolve()
    if recorded_run_dir and not Path(recorded_run_dir).is_absolute():
        depth = len(Path(recorded_run_dir).parts)
        if depth <= len(run_dir.parents) and run_dir.parts[-depth:] == Path(recorded_run_dir).parts:
            candidates.insert(0, run_dir.parents[depth - 1] / path)
    return next((c.resolve() for c in candidates if c.exists()), None)


def checkpoint_starts(policy: str, checkpoint: str) -> TrainingStarts:
    """The starts one checkpoint trained on, for the policies that have training data."""
    if policy in ("bc", "ppo"):
        from ..policies.learned import read_config, resolve_checkpoint

        folder = resolve_checkpoint(checkpoint, policy)
        config = read_config(folder)
        train = config.get("train", {})
        if config.get("algorithm") == "bc":
            dataset = _recorded_path(train.get("dataset"), folder.parent, train.get("out"))
            return dataset_starts(dataset) if dataset else TrainingStarts(untraced=[str(folder)])
        out = ppo_starts(folder, train)
        if config.get("init_bc"):
            out.add(checkpoint_starts("bc", config["init_bc"]))
        return out
    from ..policies.lerobot_policies import resolve_checkpoint as resolve_lerobot

    folder = resolve_lerobot(checkpoint, policy)
    train_config = folder / "train_config.json"
    if not train_config.is_file():
        return TrainingStarts(untraced=[str(folder)])
    recorded = json.loads(train_config.read_text())
    # lerobot-train writes OUTPUT/checkpoints/<step>/pretrained_model
    dataset = _recorded_path(recorded.get("dataset", {}).get("root"), folder.parents[2], recorded.get("output_dir"))
    return dataset_starts(dataset) if dataset else TrainingStarts(untraced=[str(folder)])


def ppo_starts(folder: Path, train: dict) -> TrainingStarts:
    """A PPO run resets its env with seeds seed * stride + k for the k-th episode it started (objects cycle)."""
    import torch

    from ..train.ppo import RESET_SEED_STRIDE

    state_path = folder / "train_state.pt"
    if not state_path.is_file():
        return TrainingStarts(untraced=[str(folder)])
    started = int(torch.load(state_path, weights_only=False)["episodes_started"])
    base = int(train["seed"]) * RESET_SEED_STRIDE
    starts = {(train["setting"], train["skill"], None, base + k) for k in range(started)}
    return TrainingStarts(starts, sources=[f"{folder.parent.resolve()} ({started} PPO episodes)"])


def training_starts(policy: str, checkpoint: str | None) -> TrainingStarts:
    """Everything the policy's checkpoints (each skill's, for a `pick=A,place=B` mapping) trained on."""
    out = TrainingStarts()
    if policy in ("expert", "random") or not checkpoint:
        return out
    for path in split_checkpoints(checkpoint).values():
        out.add(checkpoint_starts(policy, path))
    return out


def plan_start_skill(setting: str, skill: str) -> str:
    """The skill an episode starts with: itself, or a chain's first stage (its start is that skill's start)."""
    chains = get_setting(setting).chains
    return chains[skill][0].skill if skill in chains else skill


def seen_in_training(setting: str, plans: list[EpisodePlan], starts: TrainingStarts) -> list[int]:
    """Indices of the planned evaluation episodes whose start the policy trained on."""
    return [p.index for p in plans if starts.seen(setting, plan_start_skill(setting, p.skill), p.object, p.seed)]
