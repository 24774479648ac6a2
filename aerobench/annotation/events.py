"""Event times and signal summaries from one trajectory's recorded per-step signals.

Spec: Sec. "Event Annotation for Aerial Manipulation" and appendix "Trajectory Annotation and Outcome
Categorization". For a binary event predicate b_t the event time is t_b = min{t : b_t = 1}, with t_b = infinity
(here `None`) if it is never observed. Event times are independent observations, not an assumed stage order.

Input everywhere: `signals`, a mapping from the env's info key names (`aerobench.envs.checker.COMMON_INFO_KEYS`,
`SKILL_INFO_KEYS`) to `(T,)` arrays (numpy or CPU torch) of one env's T control steps.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields

import numpy as np

from ..envs.checks import SafetyLimits

Signals = Mapping[str, np.ndarray]

SKILLS = ("pick", "place", "nav", "open", "close")
ARTICULATION_SKILLS = ("open", "close")
OBJECT_SKILLS = ("pick", "place", "nav")  # nav carries the object inside a chain

_LIMITS = SafetyLimits()
NONTARGET_CONTACT_N = _LIMITS.collision_force_n  # spec "non-target contact"; the env's collision threshold
AIRFRAME_CONTACT_N = _LIMITS.collision_force_n
PAYLOAD_LOSS_STEPS = _LIMITS.unsupported_release_steps  # ungrasped and unsupported this long: the payload is lost
PLATFORM_STABLE_MPS = 0.025  # spec Place: "platform speed remains below 0.025 m/s ...
PLATFORM_STABLE_STEPS = 20  # ... for 20 consecutive control steps"
CLEARANCE_M = 0.03  # spec Open/Close: "minimum sampled distance of 0.03 m ... throughout the rollout"

# Signals every skill's annotation reads (envelope flags rather than re-thresholded tilt / altitude, so the
# thresholds live once, in `SafetyLimits`).
COMMON_KEYS = (
    "success", "fail_cause", "fail_tilt", "fail_low", "fail_high", "fail_workspace",
    "nontarget_contact_force", "airframe_contact_force", "speed", "min_obstacle_clearance",
)
SKILL_KEYS = {
    "pick": ("is_grasped", "is_lifted"),
    "place": ("is_grasped", "is_aligned", "is_support_contact", "is_released", "is_gripper_clear"),
    "nav": ("is_nav_reached",),
    "open": ("is_handle_pinched", "is_goal_reached", "articulation_progress", "is_released_handle",
             "is_arm_retracted", "is_platform_stable", "no_airframe_contact", "min_clearance", "phase"),
}
SKILL_KEYS["close"] = SKILL_KEYS["open"]
# Read where present: support evidence for payload loss (the env reports it whenever there is an object), and the
# initialization flag.
OPTIONAL_KEYS = ("is_object_supported", "init_failed")


def required_keys(skill: str) -> tuple[str, ...]:
    """Every signal `categorize(skill, ...)` needs."""
    check_skill(skill)
    return COMMON_KEYS + SKILL_KEYS[skill]


def check_skill(skill: str) -> None:
    if skill not in SKILLS:
        raise ValueError(f"unknown skill {skill!r}; valid skills: {', '.join(SKILLS)}")


def signal(signals: Signals, key: str) -> np.ndarray:
    """`signals[key]` as a 1-D numpy array (torch tensors are copied to the CPU)."""
    if key not in signals:
        raise KeyError(f"the trace has no {key!r} signal; recorded keys: {', '.join(sorted(signals))}")
    value = signals[key]
    if hasattr(value, "detach"):
        value = value.detach().cpu().numpy()
    array = np.asarray(value)
    if array.ndim != 1:
        raise ValueError(f"signal {key!r} has shape {array.shape}; expected (T,) for one env's T control steps")
    return array


def trace_length(signals: Signals) -> int:
    """T, the number of recorded control steps; every signal must have it."""
    lengths = {key: len(signal(signals, key)) for key in signals}
    if len(set(lengths.values())) > 1:
        raise ValueError(f"signals of different lengths: {lengths}")
    return next(iter(lengths.values()), 0)


def slice_signals(signals: Signals, start: int, stop: int) -> dict[str, np.ndarray]:
    """Every signal restricted to control steps [start, stop)."""
    return {key: signal(signals, key)[start:stop] for key in signals}


def first_time(flags: np.ndarray) -> int | None:
    """Spec t_b = min{t : b_t = 1}; `None` stands for infinity (never observed)."""
    hits = np.flatnonzero(np.asarray(flags, dtype=bool))
    return int(hits[0]) if hits.size else None


def first_streak(flags: np.ndarray, length: int) -> int | None:
    """First step of the first run of at least `length` consecutive true flags (`None`: no such run)."""
    flags = np.asarray(flags, dtype=bool)
    if length < 1:
        raise ValueError(f"a streak needs length >= 1, got {length}")
    run = 0
    for t, flag in enumerate(flags):
        run = run + 1 if flag else 0
        if run == length:
            return t - length + 1
    return None


@dataclass(frozen=True)
class Events:
    """Event times (control steps from the trace's first step; `None` = never observed or not the skill's event)."""

    # Pick (spec): first grasp, first lift.
    t_g: int | None = None
    t_l: int | None = None
    # Place (spec): first overhead alignment, support contact, release, gripper clearance.
    t_o: int | None = None
    t_d: int | None = None
    t_r: int | None = None
    t_c: int | None = None
    # Nav: first time within reach of the target.
    t_reach: int | None = None
    # Open / Close: first handle pinch, first articulation goal; progress extremes (normalized q-bar).
    t_pinch: int | None = None
    t_goal: int | None = None
    max_progress: float | None = None
    min_progress: float | None = None
    # Aerial operating constraints, every skill (spec Sec. "Event Annotation").
    t_tilt: int | None = None  # excessive tilt
    t_low: int | None = None  # altitude below the lower bound
    t_high: int | None = None  # altitude above the upper bound
    t_workspace: int | None = None  # outside the workspace
    t_contact: int | None = None  # non-target contact above NONTARGET_CONTACT_N
    t_airframe_contact: int | None = None  # airframe contact above AIRFRAME_CONTACT_N (Open/Close: the N check)
    t_payload_loss: int | None = None  # a held object lost before any release
    t_stable: int | None = None  # first step of the first platform-stability streak
    t_clearance: int | None = None  # clearance below CLEARANCE_M
    # Outcome flags.
    t_success: int | None = None
    t_fail: int | None = None  # first latched failure (fail_cause != 0)

    def as_dict(self) -> dict[str, int | float | None]:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: Mapping[str, int | float | None]) -> Events:
        known = {f.name for f in fields(cls)}
        unknown = set(values) - known
        if unknown:
            raise ValueError(f"unknown event names {sorted(unknown)}; known: {sorted(known)}")
        return cls(**values)


def payload_loss_time(signals: Signals) -> int | None:
    """First step of a run of PAYLOAD_LOSS_STEPS steps in which a previously grasped object is neither grasped nor
    supported, before any release was registered (a deliberate release is not a loss)."""
    if "is_grasped" not in signals:
        return None
    grasped = signal(signals, "is_grasped").astype(bool)
    supported = np.zeros_like(grasped)
    for key in ("is_object_supported", "is_support_contact"):
        if key in signals:
            supported |= signal(signals, key).astype(bool)
    released = np.zeros_like(grasped)
    if "is_released" in signals:
        released = np.logical_or.accumulate(signal(signals, "is_released").astype(bool))
    held_before = np.concatenate([[False], np.logical_or.accumulate(grasped)[:-1]])
    return first_streak(held_before & ~grasped & ~supported & ~released, PAYLOAD_LOSS_STEPS)


def extract_events(skill: str, signals: Signals) -> Events:
    """The spec's event times for `skill` (Pick t_g, t_l; Place t_o, t_d, t_r, t_c) plus the aerial-constraint events
    every skill records (tilt, altitude, workspace, non-target and airframe contact, payload loss, platform
    stability, clearance) and the articulation progress of Open / Close."""
    missing = [k for k in required_keys(skill) if k not in signals]
    if missing:
        raise KeyError(f"{skill} annotation needs signals {missing}; recorded keys: {', '.join(sorted(signals))}")

    def first(key: str) -> int | None:
        return first_time(signal(signals, key))

    task: dict[str, int | float | None] = {}
    if skill == "pick":
        task = {"t_g": first("is_grasped"), "t_l": first("is_lifted")}
    elif skill == "place":
        task = {"t_o": first("is_aligned"), "t_d": first("is_support_contact"), "t_r": first("is_released"),
                "t_c": first("is_gripper_clear")}
    elif skill == "nav":
        task = {"t_reach": first("is_nav_reached")}
    else:
        progress = signal(signals, "articulation_progress").astype(float)
        task = {"t_pinch": first("is_handle_pinched"), "t_goal": first("is_goal_reached"),
                "max_progress": float(progress.max()) if progress.size else None,
                "min_progress": float(progress.min()) if progress.size else None}

    if skill in ARTICULATION_SKILLS:  # the signals of the spec's N, V and C checks, so events and checks agree
        airframe_contact = ~signal(signals, "no_airframe_contact").astype(bool)
        stable = signal(signals, "is_platform_stable").astype(bool)
        clearance = signal(signals, "min_clearance")
    else:
        airframe_contact = signal(signals, "airframe_contact_force") > AIRFRAME_CONTACT_N
        stable = signal(signals, "speed") < PLATFORM_STABLE_MPS
        clearance = signal(signals, "min_obstacle_clearance")
    return Events(
        **task,
        t_tilt=first("fail_tilt"),
        t_low=first("fail_low"),
        t_high=first("fail_high"),
        t_workspace=first("fail_workspace"),
        t_contact=first_time(signal(signals, "nontarget_contact_force") > NONTARGET_CONTACT_N),
        t_airframe_contact=first_time(airframe_contact),
        t_payload_loss=payload_loss_time(signals) if skill in OBJECT_SKILLS else None,
        t_stable=first_streak(stable, PLATFORM_STABLE_STEPS),
        t_clearance=first_time(clearance < CLEARANCE_M),
        t_success=first("success"),
        t_fail=first_time(signal(signals, "fail_cause") != 0),
    )


# The diagnostic signals every record keeps (spec: "all underlying diagnostic signals are retained"), as data:
# (diagnostic name, signal key, reduction, skills it applies to). Rows whose signal a trace lacks are skipped;
# skill filters matter in chains, where another stage's signals read 0.
EVERY_SKILL = SKILLS
DIAGNOSTICS: tuple[tuple[str, str, str, tuple[str, ...]], ...] = (
    ("max_tilt_rad", "tilt", "max", EVERY_SKILL),
    ("min_altitude_m", "altitude", "min", EVERY_SKILL),
    ("max_altitude_m", "altitude", "max", EVERY_SKILL),
    ("max_speed_mps", "speed", "max", EVERY_SKILL),
    ("final_speed_mps", "speed", "final", EVERY_SKILL),
    ("max_angular_speed_radps", "angular_speed", "max", EVERY_SKILL),
    ("max_nontarget_contact_force_n", "nontarget_contact_force", "max", EVERY_SKILL),
    ("max_airframe_contact_force_n", "airframe_contact_force", "max", EVERY_SKILL),
    ("min_obstacle_clearance_m", "min_obstacle_clearance", "min", EVERY_SKILL),
    ("rotor_saturated_steps", "rotor_saturated", "count", EVERY_SKILL),  # where recorded (`rotor_statistics`)
    ("fail_tilt_steps", "fail_tilt", "count", EVERY_SKILL),  # every envelope flag, not only the first latched cause
    ("fail_low_steps", "fail_low", "count", EVERY_SKILL),
    ("fail_high_steps", "fail_high", "count", EVERY_SKILL),
    ("fail_workspace_steps", "fail_workspace", "count", EVERY_SKILL),
    ("grasped_steps", "is_grasped", "count", OBJECT_SKILLS),
    ("max_lift_height_m", "lift_height", "max", ("pick",)),
    ("lifted_steps", "is_lifted", "count", ("pick",)),
    ("min_tcp_to_grasp_point_m", "tcp_to_grasp_point", "min", ("pick",)),
    ("min_goal_distance_m", "goal_distance", "min", ("place",)),
    ("final_goal_distance_m", "goal_distance", "final", ("place",)),
    ("support_contact_steps", "is_support_contact", "count", ("place",)),
    ("max_collision_impulse_ns", "collision_impulse", "max", ("place",)),
    ("max_platform_stable_steps", "platform_stable_steps", "max", ("place",)),
    ("min_nav_distance_m", "nav_distance", "min", ("nav",)),
    ("final_nav_distance_m", "nav_distance", "final", ("nav",)),
    ("max_nav_settle_steps", "nav_settle_steps", "max", ("nav",)),
    ("final_articulation_progress", "articulation_progress", "final", ARTICULATION_SKILLS),
    ("handle_pinched_steps", "is_handle_pinched", "count", ARTICULATION_SKILLS),
    ("min_clearance_m", "min_clearance", "min", ARTICULATION_SKILLS),
)
_REDUCE = {"max": np.max, "min": np.min, "final": lambda a: a[-1], "count": lambda a: np.count_nonzero(a)}


def _plain(value) -> float | int | bool | None:
    """A JSON-ready Python scalar; non-finite floats become `None` (JSON has no infinity or NaN)."""
    value = value.item() if isinstance(value, np.generic) else value
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def summarize(skill: str, signals: Signals) -> dict[str, float | int | bool | None]:
    """The `DIAGNOSTICS` rows of `skill` that the trace has signals for (an empty trace has none)."""
    check_skill(skill)
    out: dict[str, float | int | bool | None] = {}
    for name, key, reduction, skills in DIAGNOSTICS:
        if skill not in skills or key not in signals:
            continue
        values = signal(signals, key)
        if values.size:
            out[name] = _plain(_REDUCE[reduction](values))
    return out
