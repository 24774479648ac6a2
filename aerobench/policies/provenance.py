"""What a learned policy trained on: the episode starts of its training data.

`aerobench generate` and `aerobench eval` share the rollout runner's seeded plan, so an evaluation with the seed the
training data was generated with replays the demonstrations' own starts (same setting, skill, object and env seed).
A policy says which starts it trained on (`training_starts` on its class, asked through the registry), and the
evaluator counts its planned episodes among them. aerobench's own trainers write the starts into the checkpoint
(`starts.json`), so a checkpoint copied anywhere (e.g. committed under `leaderboards/checkpoints/`) still knows them;
a LeRobot checkpoint is traced through the dataset its `train_config.json` names.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

STARTS_FILE = "starts.json"
DATASET_EPISODES = "meta/aerobench_episodes.jsonl"  # an aerobench export's per-episode annotation (docs/datasets.md)

# An episode start: (setting, skill, object, env seed); object None matches any object (RL resets cycle objects).
Start = tuple[str, str, "str | None", int]
# A run of consecutive env seeds (an RL run's resets): (setting, skill, first seed, count).
SeedRange = tuple[str, str, int, int]


@dataclass
class TrainingStarts:
    starts: set[Start] = field(default_factory=set)
    ranges: list[SeedRange] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)  # datasets / RL runs the starts come from
    untraced: list[str] = field(default_factory=list)  # checkpoints whose training data could not be found

    def add(self, other: TrainingStarts) -> None:
        self.starts |= other.starts
        self.ranges += [r for r in other.ranges if r not in self.ranges]
        self.sources += [s for s in other.sources if s not in self.sources]
        self.untraced += [s for s in other.untraced if s not in self.untraced]

    def seen(self, setting: str, skill: str, obj: str | None, seed: int) -> bool:
        if (setting, skill, obj, seed) in self.starts or (setting, skill, None, seed) in self.starts:
            return True
        return any(s == setting and k == skill and first <= seed < first + n for s, k, first, n in self.ranges)

    def as_dict(self) -> dict:
        return {"starts": sorted([list(s) for s in self.starts], key=lambda s: (s[0], s[1], s[2] or "", s[3])),
                "ranges": [list(r) for r in self.ranges], "sources": self.sources}

    @classmethod
    def from_dict(cls, d: dict) -> TrainingStarts:
        return cls({tuple(s) for s in d.get("starts", [])}, [tuple(r) for r in d.get("ranges", [])],
                   list(d.get("sources", [])))


def write_starts(folder: Path, starts: TrainingStarts) -> None:
    (folder / STARTS_FILE).write_text(json.dumps(starts.as_dict()) + "\n")


def read_starts(folder: Path) -> TrainingStarts:
    """The starts a checkpoint folder carries; a folder without `starts.json` is reported as untraced."""
    path = folder / STARTS_FILE
    if not path.is_file():
        return TrainingStarts(untraced=[str(folder)])
    return TrainingStarts.from_dict(json.loads(path.read_text()))


def dataset_starts(root: Path, source: str | None = None) -> TrainingStarts:
    """Every episode start recorded in an exported dataset's annotations (all outcomes: a LeRobot policy trains on
    every episode, BC on the successful ones; counting all of them is the safe side)."""
    path = Path(root) / DATASET_EPISODES
    if not path.is_file():
        return TrainingStarts(untraced=[str(root)])
    starts = set()
    for line in path.read_text().splitlines():
        if line.strip():
            r = json.loads(line)
            starts.add((r["setting"], r["skill"], r.get("object"), int(r["seed"])))
    return TrainingStarts(starts, sources=[source or str(root)])


def recorded_path(path: str | None, run_dir: Path, recorded_run_dir: str | None) -> Path | None:
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
