"""What a leaderboard row is, in columns: a short name, its comparison group, and its training recipe as its
checkpoints record it.

A results file names its checkpoints (`provenance.checkpoint`: one folder, or `pick=DIR,place=DIR`; a pooled row's
`training_runs.checkpoints`); the committed ones under `leaderboards/checkpoints/` carry how they were trained:
an aerobench BC checkpoint's `config.json` its data (`data.episodes`, `data.frames`), gradient steps and seed; a PPO
checkpoint its environment steps, seed and the BC checkpoint it started from; a LeRobot checkpoint its
`train_config.json` (steps, batch, seed); every checkpoint its training starts (`starts.json`: one per demonstration).
DART / DAgger are read from the names of the training data (`dataset`, `starts.json` sources), which say so. What no
file records is shown as "-", never guessed; a checkpoint that is not in the repository is marked.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

from ..envs.tasks import SKILLS
from .results import DEFAULT_TIERS, UNKNOWN_TIER

SHORT_LABEL_CHARS = 30  # a label up to this long is the row's name; a longer one gives way to its file's name
UNKNOWN = "-"


def tier_of_result(result: dict) -> str:
    """A results file's input tier; files written before the field existed: the expert's and random's, else unknown."""
    return result.get("inputs") or DEFAULT_TIERS.get(result["policy"], UNKNOWN_TIER)


def solver_text(result: dict) -> str:
    """The PhysX solver the row was measured with; results from before the key were measured under TGS."""
    return str(result["provenance"].get("physx_solver", "tgs")).upper()


def _stem(source: str, setting: str) -> str:
    stem = Path(source.strip()).stem
    return stem[len(setting) + 1:] if stem.startswith(f"{setting}_") else stem


def short_labels(results: list[dict]) -> dict[int, str]:
    """`{id(result): name}`: the label where it is short, else the results file's name without the setting (a pooled
    row's files without their `_s<seed>` suffix); the full label where that would not be unique or says nothing."""
    names = {}
    for result in results:
        name = result["label"]
        if len(name) > SHORT_LABEL_CHARS:
            stems = {re.sub(r"_s\d+$", "", _stem(s, result["setting"])) if result.get("training_runs") else
                     _stem(s, result["setting"]) for s in str(result.get("_source", "")).split(" + ")}
            if len(stems) == 1 and (stem := stems.pop()) not in ("", "results"):
                name = stem
        names[id(result)] = name
    taken = list(names.values())
    return {key: (name if taken.count(name) == 1 else next(r["label"] for r in results if id(r) == key))
            for key, name in names.items()}


@dataclass(frozen=True)
class GroupKey:
    """What makes rows comparable: the same protocol (skills, or a chained protocol), the same starts (`--seed`),
    the same contact solver and the same evaluation condition (none: today's physics); smoke runs (truncated
    episodes, one episode per cell) stand apart."""

    smoke: bool
    chain: tuple[str, ...]
    skills: tuple[str, ...]
    seed: int | None
    solver: str
    condition: str = ""  # "wind_gusty_3ms v1", a real-time setting (comma-separated when several); "" without one

    def order(self) -> tuple:
        """A total order (a seed may be unknown)."""
        return self.smoke, self.chain, self.skills, self.seed is None, self.seed or 0, self.solver, self.condition

    def title(self) -> str:
        if self.chain:
            protocol = f"Chained protocol {', '.join(self.skills)} ({' -> '.join(self.chain)})"
        elif len(self.skills) == 1 and "_" in self.skills[0] or self.skills == ("deliver",):
            protocol = f"{self.skills[0].capitalize()} (one policy over the whole chain)"
        else:
            protocol = ", ".join(s.capitalize() for s in self.skills)
        smoke = "smoke / plumbing runs, not comparable: " if self.smoke else ""
        condition = f"; condition {self.condition}" if self.condition else ""
        return (f"{smoke}{protocol}; starts of --seed {self.seed if self.seed is not None else '-'}; {self.solver}"
                f"{condition}")


def perturbation(result: dict) -> str:
    """What the run changed from the nominal evaluation: its conditions and real-time settings ("" when nothing)."""
    provenance = result["provenance"]
    parts = [f"{c['name']} v{c['version']}" for c in provenance.get("conditions") or ()]
    parts += list(provenance.get("condition") or ()) if not parts else []
    realtime = provenance.get("realtime")
    if realtime:
        latency = realtime.get("latency_ms")
        latency = "measured latency" if latency == "measured" else f"{float(latency):g} ms"
        parts.append(f"real time ({latency}, hold {realtime.get('hold')}, {realtime.get('schedule')})")
    return ", ".join(parts)


def group_key(result: dict) -> GroupKey:
    provenance = result["provenance"]
    rank = {s: i for i, s in enumerate(SKILLS)}
    skills = tuple(sorted({c["skill"] for c in result["cells"] if c["n"]}, key=lambda s: (rank.get(s, 99), s)))
    smoke = provenance.get("max_steps") is not None or max((c["n"] for c in result["cells"]), default=0) <= 1
    # eval records name, version and parameters; a summary of records keeps the run's names (run.json)
    condition = perturbation(result)
    return GroupKey(smoke, tuple(provenance.get("chain") or ()), skills, provenance.get("seed"), solver_text(result),
                    condition)


def checkpoints_of(result: dict) -> list[list[tuple[str | None, str]]]:
    """Per training run, `(skill or None, folder)` of each checkpoint the row names; [] for expert / random."""
    runs = (result.get("training_runs") or {}).get("checkpoints") or [result["provenance"].get("checkpoint")]
    out = []
    for text in runs:
        if not text:
            continue
        parts = [p.split("=", 1) if "=" in p else (None, p) for p in str(text).split(",") if p]
        out.append([(skill, folder) for skill, folder in parts])
    return out


def find_checkpoint(folder: str, result: dict) -> Path | None:
    """The checkpoint folder as recorded (relative to where the eval ran, the repository root): looked for above the
    results file, then from the current directory."""
    path = Path(folder)
    if path.is_absolute():
        return path if path.is_dir() else None
    anchors = [*Path(result["_path"]).parents] if result.get("_path") else []
    for anchor in [*anchors, Path.cwd()]:
        if (anchor / path).is_dir():
            return anchor / path
    return None


def _read(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def _thousands(n: int) -> str:
    for size, suffix in ((1_000_000, "M"), (1_000, "k")):
        if n >= size:
            return f"{n / size:.3g}{suffix}"
    return str(n)


def _collection(names: list[str]) -> str:
    text = " ".join(names).lower()
    return " (DAgger)" if "dagger" in text else (" (DART)" if "dart" in text else "")


@dataclass(frozen=True)
class Recipe:
    """One checkpoint's training, as its files say: data, budget and seed texts ("-" where unknown)."""

    data: str = UNKNOWN
    budget: str = UNKNOWN
    seed: str = UNKNOWN


def recipe(folder: Path | None, result: dict) -> Recipe:
    """The recipe of the checkpoint in `folder` (None: not found) of `result`'s row."""
    if folder is None:
        return Recipe()
    config, starts = _read(folder / "config.json"), _read(folder / "starts.json")
    sources = [str(s) for s in starts.get("sources", [])]
    demos = f"{len(starts['starts'])} demos" if "starts" in starts else None
    train = config.get("train", {})
    settings = sorted({str(start[0]) for start in starts.get("starts", [])} - {result.get("setting")})
    where = f" on {', '.join(settings)}" if settings else ""  # trained on another setting's starts
    if config.get("algorithm") == "bc":
        data = config.get("data", {})
        text = f"{data['episodes']} demos, {_thousands(data['frames'])} transitions" if "episodes" in data else demos
        return Recipe(f"{text}{_collection([str(train.get('dataset', '')), *sources])}{where}" if text else UNKNOWN,
                      f"{_thousands(train['steps'])} steps" if "steps" in train else UNKNOWN, str(train.get("seed", UNKNOWN)))
    if config.get("algorithm") == "ppo":
        init = train.get("init_bc")
        start = recipe(find_checkpoint(init, result) if init else None, result)
        data = f"BC init on {start.data}" if init else "none (RL from scratch)"
        budget = f"{_thousands(train['total_steps'])} env steps" if "total_steps" in train else UNKNOWN
        return Recipe(data, budget, str(train.get("seed", UNKNOWN)))
    lerobot = _read(folder / "train_config.json")
    if lerobot:
        dataset = lerobot.get("dataset") or {}
        steps, batch = lerobot.get("steps"), lerobot.get("batch_size")
        budget = f"{_thousands(steps)} steps, batch {batch}" if steps else UNKNOWN
        names = [str(dataset.get("root", "")), str(dataset.get("repo_id", "")), *sources]
        return Recipe(f"{demos}{_collection(names)}{where}" if demos else UNKNOWN, budget,
                      str(lerobot.get("seed", UNKNOWN)))
    return Recipe(f"{demos}{where}" if demos else UNKNOWN)


def _joined(per_skill: list[tuple[str | None, str]]) -> str:
    """One text where every checkpoint says the same, else "skill: text; ..."."""
    texts = {text for _, text in per_skill}
    if len(texts) == 1:
        return texts.pop()
    return "; ".join(f"{skill}: {text}" if skill else text for skill, text in per_skill)


@dataclass(frozen=True)
class RowFacts:
    data: str
    budget: str
    seeds: str
    missing: tuple[str, ...]  # checkpoint folders the repository does not hold


def row_facts(result: dict) -> RowFacts:
    runs = checkpoints_of(result)
    if not runs:
        return RowFacts(UNKNOWN, UNKNOWN, UNKNOWN, ())
    found = [[(skill, folder, find_checkpoint(folder, result)) for skill, folder in run] for run in runs]
    recipes = [[(skill, recipe(path, result)) for skill, _, path in run] for run in found]
    missing = tuple(folder for run in found for _, folder, path in run if path is None)
    first = recipes[0]
    data = _joined([(s, r.data) for s, r in first])
    budget = _joined([(s, r.budget) for s, r in first])
    seeds = [_joined([(s, r.seed) for s, r in run]) for run in recipes]
    if len(seeds) == 1:
        seed_text = seeds[0]
    else:
        seed_text = f"{len(seeds)} runs" + (": " + ", ".join(seeds) if set(seeds) != {UNKNOWN} else "")
    return RowFacts(data, budget, seed_text, missing)


def time_to_success_text(result: dict) -> str:
    """Per skill, the median over the object cells of each cell's median seconds to success; "-" where the results
    file predates the field or nothing succeeded."""
    per_skill: dict[str, list[float]] = {}
    for c in result["cells"]:
        if c.get("time_to_success_s") is not None:
            per_skill.setdefault(c["skill"], []).append(c["time_to_success_s"])
    if not per_skill:
        return UNKNOWN
    parts = []
    for skill, values in per_skill.items():
        values = sorted(values)
        mid = len(values) // 2
        median = values[mid] if len(values) % 2 else (values[mid - 1] + values[mid]) / 2
        parts.append(f"{skill} {median:.1f}")
    return ", ".join(parts)
