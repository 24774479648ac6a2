"""Input tiers: what a policy may read, defined once and carried by every dataset, checkpoint and results file.

A benchmark row means something only with the inputs that earned it. aerobench knows two tiers (../DESIGN.md,
"Input tiers"):

- `privileged`: what the simulator knows. Besides everything `vision` has, the relative task state
  (`observation.environment_state`, `envs.observations.TASK_STATE_FIELDS`: live object and goal poses, contact-based
  grasp confirmation, set-down time, the grasp heading planned for the object). The expert acts on the simulator's
  state directly and is `privileged` too.
- `vision`: the spec's VLA inputs and nothing else (spec, "Problem Formulation": o_t = (I_t, s_t, l); appendix
  "Observation Space"): the three onboard RGB-D cameras (`observation.images.<camera>`, `observation.depth.<camera>`,
  128x128), the proprioceptive state (`observation.state`: 19 values, 25 with the arm) and the language
  instruction (`task`). Where a goal is a point only the simulator knows (Place's spot, Nav's target), the scene
  shows it as a visual-only marker (`envs.skills.markers`) and the instruction names it.

Results files add `none` for a policy that reads nothing (random). Rows of different tiers are never ranked against
each other (`eval.leaderboard`), and a policy that reads a feature outside the tier it is trained or evaluated for
is refused with one line (`check_features`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

# LeRobot's feature keys (lerobot.utils.constants) and aerobench's depth key, as prefixes: a camera's key adds its name
STATE = "observation.state"
ENVIRONMENT_STATE = "observation.environment_state"
IMAGES = "observation.images."
DEPTH = "observation.depth."
INSTRUCTION = "task"


@dataclass(frozen=True)
class InputTier:
    """A tier: its name, what it admits (feature keys, or key prefixes ending in '.'), and where the spec says so."""

    name: str
    admits: tuple[str, ...]
    meaning: str
    source: str

    def admits_feature(self, key: str) -> bool:
        return any(key.startswith(a) if a.endswith(".") else key == a for a in self.admits)


VISION = InputTier(
    "vision", (STATE, IMAGES, DEPTH, INSTRUCTION),
    "the three RGB-D cameras, the proprioceptive state and the instruction (goals only the simulator knows are "
    "shown as markers)",
    "spec, Problem Formulation (o_t = (I_t, s_t, l)) and appendix Observation Space",
)
PRIVILEGED = InputTier(
    "privileged", (*VISION.admits, ENVIRONMENT_STATE),
    "everything vision has plus the simulator's relative task state (live poses, contacts, grasp confirmation)",
    "the privileged expert and state-based learners (spec, Skill Policy Learning); envs.observations",
)
TIERS: dict[str, InputTier] = {t.name: t for t in (VISION, PRIVILEGED)}  # narrowest first
NO_INPUTS = "none"  # a results file's tier for a policy that reads nothing (random)
RESULT_TIERS = (*TIERS, NO_INPUTS)


def get_tier(name: str) -> InputTier:
    try:
        return TIERS[name]
    except KeyError:
        raise ValueError(f"unknown input tier {name!r}; valid tiers: {', '.join(TIERS)}") from None


def tier_of(features: Iterable[str]) -> str:
    """The narrowest tier that admits every feature key of `features` (`none` for no feature at all)."""
    features = list(features)
    if not features:
        return NO_INPUTS
    for tier in TIERS.values():
        if all(tier.admits_feature(f) for f in features):
            return tier.name
    unknown = [f for f in features if not PRIVILEGED.admits_feature(f)]
    raise ValueError(f"input features {unknown} belong to no tier ({', '.join(TIERS)}); valid keys start with "
                     f"{', '.join(PRIVILEGED.admits)}")


def check_features(features: Iterable[str], tier: str, who: str) -> None:
    """Refuse (one line) a policy `who` that reads a feature outside `tier`."""
    wanted = get_tier(tier)
    outside = [f for f in features if not wanted.admits_feature(f)]
    if outside:
        raise ValueError(f"{who} reads {', '.join(outside)}, which the {tier} tier does not admit ({wanted.meaning}); "
                         f"drop {'them' if len(outside) > 1 else 'it'} or use the {tier_of(features)} tier")


def tier_rank(name: str) -> int:
    """Order of tiers for tables: vision, privileged, none."""
    return RESULT_TIERS.index(name) if name in RESULT_TIERS else len(RESULT_TIERS)


def widest(names: Iterable[str]) -> str:
    """The widest of result tiers (privileged > vision > none): a row of several checkpoints reads what any reads."""
    order = (NO_INPUTS, *TIERS)
    return max(names, key=order.index, default=NO_INPUTS)
