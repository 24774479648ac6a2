"""The episode record: one JSON object per episode, shared by data generation (dataset annotations) and evaluation.

DESIGN "Episode record": ids (episode, parent trajectory, seed, shard), setting, skill (or chain name), object,
platform, policy, outcome (S/F/T, or I for an initialization failure), mode, primary cause, event times, steps,
duration, the skill segments of a chain and the retained diagnostics. JSON has no infinity: an event never
observed is `null`, as is a non-finite diagnostic. `to_json` / `from_json` round-trip exactly.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from ..envs.platforms import CONTROL_HZ
from .modes import Outcome, OutcomeCode
from .segments import Segment

RECORD_VERSION = 1
OUTCOME_CODES = tuple(str(code) for code in OutcomeCode)


def _numpy_scalar(value):
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON-serializable in an episode record")


def _canonical(value):
    """The value as JSON reads it back (lists, dicts, Python scalars), so a record equals its round trip."""
    return json.loads(json.dumps(value, default=_numpy_scalar, allow_nan=False))


@dataclass(frozen=True)
class EpisodeRecord:
    """One episode's annotation. `duration_s` is derived: steps / CONTROL_HZ (20 Hz)."""

    episode_index: int
    parent_id: str
    seed: int | None
    shard: int
    setting: str
    skill: str  # skill name, or the chain's name for a sequential rollout
    object: str
    platform: str
    policy: str
    outcome: str
    mode: str
    cause: str
    events: Mapping[str, int | float | None]
    steps: int
    segments: tuple[Mapping, ...] = ()
    diagnostics: Mapping[str, float | int | bool | str | None] = field(default_factory=dict)
    version: int = RECORD_VERSION
    duration_s: float = field(init=False)

    def __post_init__(self):
        for name in ("episode_index", "shard", "steps"):  # numpy integers from a rollout become plain ints
            object.__setattr__(self, name, int(getattr(self, name)))
        if self.seed is not None:
            object.__setattr__(self, "seed", int(self.seed))
        object.__setattr__(self, "outcome", str(self.outcome))
        if self.outcome not in OUTCOME_CODES:
            raise ValueError(f"outcome {self.outcome!r} is not one of {OUTCOME_CODES}")
        if self.version != RECORD_VERSION:
            raise ValueError(f"record version {self.version}; this aerobench reads version {RECORD_VERSION}")
        if self.steps < 0:
            raise ValueError(f"steps must be >= 0, got {self.steps}")
        object.__setattr__(self, "events", _canonical(dict(self.events)))
        object.__setattr__(self, "diagnostics", _canonical(dict(self.diagnostics)))
        object.__setattr__(self, "segments", tuple(_canonical([dict(s) for s in self.segments])))
        object.__setattr__(self, "duration_s", self.steps / CONTROL_HZ)

    @classmethod
    def from_outcome(
        cls,
        outcome: Outcome,
        *,
        episode_index: int,
        parent_id: str,
        seed: int | None,
        shard: int,
        setting: str,
        skill: str | None = None,
        object: str,  # noqa: A002  (the DESIGN's field name)
        platform: str,
        policy: str,
        segments: Sequence[Segment] = (),
    ) -> EpisodeRecord:
        """A record from `categorize`'s result (and, for a chain, `cut_segments`' segments: the outcome is the final
        stage's, with its events relative to that stage's start as in its segment; `steps` is the whole rollout's)."""
        return cls(
            episode_index=episode_index, parent_id=parent_id, seed=seed, shard=shard, setting=setting,
            skill=skill or outcome.skill, object=object, platform=platform, policy=policy,
            outcome=str(outcome.outcome), mode=outcome.mode, cause=outcome.cause, events=outcome.events.as_dict(),
            steps=segments[-1].start + outcome.steps if segments else outcome.steps,
            segments=tuple(s.to_dict() for s in segments), diagnostics=outcome.diagnostics,
        )

    def to_dict(self) -> dict:
        out = asdict(self)
        out["segments"] = list(self.segments)
        return out

    def to_json(self) -> str:
        """One line of JSON (JSONL-ready), keys sorted."""
        return json.dumps(self.to_dict(), sort_keys=True, allow_nan=False)

    @classmethod
    def from_dict(cls, data: Mapping) -> EpisodeRecord:
        data = dict(data)
        version = data.get("version")
        if version != RECORD_VERSION:
            raise ValueError(f"record version {version!r}; this aerobench reads version {RECORD_VERSION}")
        duration = data.pop("duration_s", None)
        known = {f.name for f in fields(cls) if f.init}
        unknown, missing = set(data) - known, known - set(data)
        if unknown or missing:
            raise ValueError(f"episode record fields: unknown {sorted(unknown)}, missing {sorted(missing)}")
        record = cls(**data)
        if duration is not None and duration != record.duration_s:
            raise ValueError(f"duration_s {duration} does not match steps {record.steps} at {CONTROL_HZ} Hz")
        return record

    @classmethod
    def from_json(cls, text: str) -> EpisodeRecord:
        return cls.from_dict(json.loads(text))
