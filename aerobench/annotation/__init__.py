"""Annotation: pure functions from recorded per-step signals to events, outcomes, modes, skill segments and records.

No simulator here: the inputs are one env's `(T,)` signal arrays under the env's info key names
(`aerobench.envs.checker`), and everything follows the spec's appendix "Trajectory Annotation and Outcome
Categorization".

- `events`: event times t_b = min{t : b_t = 1} (None = never), task events (Pick t_g, t_l; Place t_o, t_d, t_r,
  t_c), aerial-constraint events, and the retained diagnostic summaries.
- `modes`: S / F / T outcomes with the first latched cause, and the spec's Pick / Place / Open / Close outcome
  tables (plus a Nav table) as ordered `ModeRule`s: the first satisfied row is the mode. `Phase` codes Open/Close.
- `segments`: long-horizon rollouts cut into per-stage skill segments with their own outcomes, and the Place
  handoff-eligibility check.
- `record`: `EpisodeRecord`, the one JSON object per episode that dataset export and evaluation both write.
"""

from .events import Events, extract_events, first_streak, first_time, required_keys, summarize
from .modes import (
    CLOSE_MODES,
    MODE_TABLES,
    NAV_MODES,
    OPEN_MODES,
    PICK_MODES,
    PLACE_MODES,
    ArticulationChecks,
    Evidence,
    ModeRule,
    Outcome,
    OutcomeCode,
    Phase,
    articulation_checks,
    categorize,
    first_satisfied,
)
from .record import RECORD_VERSION, EpisodeRecord
from .segments import Segment, cut_segments, is_eligible_handoff

__all__ = [
    "CLOSE_MODES",
    "MODE_TABLES",
    "NAV_MODES",
    "OPEN_MODES",
    "PICK_MODES",
    "PLACE_MODES",
    "RECORD_VERSION",
    "ArticulationChecks",
    "EpisodeRecord",
    "Events",
    "Evidence",
    "ModeRule",
    "Outcome",
    "OutcomeCode",
    "Phase",
    "Segment",
    "articulation_checks",
    "categorize",
    "cut_segments",
    "extract_events",
    "first_satisfied",
    "first_streak",
    "first_time",
    "is_eligible_handoff",
    "required_keys",
    "summarize",
]
