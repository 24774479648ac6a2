"""Flight-test scenarios: the command each one sends over time and the metrics it reports.

A scenario is data plus two small functions; `runner.fly` executes any of them on `AeroFly-v1`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..envs.platforms import GRAVITY, MAX_SPEED_MPS, MAX_YAW_RATE_RPS, PlatformSpec
from . import metrics as M

Command = tuple[np.ndarray, float]  # world velocity (3,), yaw rate


@dataclass
class Trace:
    """What a flight recorded. Physics-rate arrays (T, ...) and control-rate arrays (K, ...)."""

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    yaw_rate: np.ndarray
    tilt_cos: np.ndarray
    xi: np.ndarray
    rotor_thrusts: np.ndarray
    mass_hat: np.ndarray
    control_t: np.ndarray
    is_grasped: np.ndarray | None = None
    reference_position: np.ndarray | None = None
    payload_kg: float = 0.0
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    default_seconds: float
    command: Callable[[Scenario, float, np.ndarray, dict], Command]
    metrics: Callable[[Trace, PlatformSpec], dict]
    scene: str = "room"
    default_payload_kg: float = 0.0
    reference_body: bool = False
    done: Callable[[dict, float], bool] | None = None  # ends the flight early (memo, time)


def _saturation_metrics(tr: Trace, platform: PlatformSpec) -> dict:
    return {
        "rotor_thrust_min_n": float(tr.rotor_thrusts.min()),
        "rotor_thrust_max_n": float(tr.rotor_thrusts.max()),
        "rotor_thrust_limit_n": platform.rotors.max_thrust_n,
        "xi_abs_max": float(np.abs(tr.xi).max()),
        "xi_limit": platform.gains.integral_limit,
        "max_tilt_deg": M.max_tilt_deg(tr.tilt_cos),
    }


# ----------------------------------------------------------------------------------------------------------------------
# hover
# ----------------------------------------------------------------------------------------------------------------------
def _zero(scn, t, p, memo) -> Command:
    return np.zeros(3), 0.0


def _hover_metrics(tr: Trace, platform: PlatformSpec) -> dict:
    last = tr.t >= tr.t[-1] - 1.0
    return {
        "max_drift_m": M.max_drift(tr.position),
        "hover_rotor_thrust_n": float(tr.rotor_thrusts[last].mean()),
        "hover_rotor_thrust_spread_n": float(np.ptp(tr.rotor_thrusts[last].mean(0))),
        "expected_rotor_thrust_n": platform.total_mass_kg * GRAVITY / 4,
        **_saturation_metrics(tr, platform),
    }


# ----------------------------------------------------------------------------------------------------------------------
# step: a 0.6 m/s velocity step along x at t = 1 s, then a 1 rad/s yaw-rate step at t = 10 s
# ----------------------------------------------------------------------------------------------------------------------
VELOCITY_STEP_T, VELOCITY_STEP_END, YAW_STEP_T = 1.0, 9.0, 10.0


def _step_command(scn, t, p, memo) -> Command:
    v = np.array([MAX_SPEED_MPS, 0.0, 0.0]) if VELOCITY_STEP_T <= t < VELOCITY_STEP_END else np.zeros(3)
    return v, (MAX_YAW_RATE_RPS if t >= YAW_STEP_T else 0.0)


def _step_metrics(tr: Trace, platform: PlatformSpec) -> dict:
    window = tr.t < VELOCITY_STEP_END
    vel = M.step_response(tr.t[window], tr.velocity[window, 0], VELOCITY_STEP_T, MAX_SPEED_MPS)
    yaw = M.step_response(tr.t, tr.yaw_rate, YAW_STEP_T, MAX_YAW_RATE_RPS)
    out = {f"velocity_{k}": v for k, v in vel.items()}
    out.update({f"yaw_rate_{k}": v for k, v in yaw.items()})
    out["cross_axis_speed_max_mps"] = float(np.abs(tr.velocity[window, 1:]).max())
    out.update(_saturation_metrics(tr, platform))
    return out


# ----------------------------------------------------------------------------------------------------------------------
# square: a 2 m waypoint square at the start altitude, by a proportional waypoint follower on the velocity command
# ----------------------------------------------------------------------------------------------------------------------
SQUARE_CORNERS_XY = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0))
WAYPOINT_GAIN, WAYPOINT_RADIUS_M, SQUARE_HOLD_S = 1.2, 0.05, 2.0


def _square_command(scn, t, p, memo) -> Command:
    waypoints = memo.setdefault("waypoints", [np.array([x, y, p[2]]) for x, y in SQUARE_CORNERS_XY])
    i = memo.setdefault("index", 0)
    if i < len(waypoints) and np.linalg.norm(waypoints[i] - p) < WAYPOINT_RADIUS_M:
        memo["index"] = i = i + 1
        memo.setdefault("reached_t", []).append(t)
    if i >= len(waypoints):
        memo.setdefault("done_t", t)
        return np.zeros(3), 0.0
    v = WAYPOINT_GAIN * (waypoints[i] - p)
    speed = np.linalg.norm(v)
    return (v * min(1.0, MAX_SPEED_MPS / speed) if speed > 0 else v), 0.0


def _square_done(memo: dict, t: float) -> bool:
    return "done_t" in memo and t >= memo["done_t"] + SQUARE_HOLD_S


def _square_metrics(tr: Trace, platform: PlatformSpec) -> dict:
    memo = tr.extra["memo"]
    reached = memo.get("reached_t", [])
    z0 = tr.position[0, 2]
    corners = [np.array([x, y, z0]) for x, y in SQUARE_CORNERS_XY]
    errors = []
    for k in range(1, min(len(reached), len(corners))):  # the sides, from one reached corner to the next
        seg = (tr.t >= reached[k - 1]) & (tr.t <= reached[k])
        errors.append(M.cross_track_error(tr.position[seg], corners[k - 1], corners[k]).max())
    out = {
        "completed": "done_t" in memo,
        "square_time_s": float(reached[-1] - reached[0]) if len(reached) >= 2 else float("nan"),
        "max_cross_track_error_m": float(max(errors)) if errors else float("nan"),
        "max_altitude_error_m": float(np.abs(tr.position[:, 2] - z0).max()),
        "xi_z_final": float(tr.xi[-1, 2]),
    }
    if tr.is_grasped is not None:
        out["grasp_held"] = bool(tr.is_grasped[1:].all())
    out.update(_saturation_metrics(tr, platform))
    return out


# ----------------------------------------------------------------------------------------------------------------------
# payload: hold the start point holding an object; the nominal controller's vertical integral must carry its weight.
# The velocity interface has no position loop, so "hover" here is the task layer's position hold (the same
# proportional follower as the square, on one waypoint): at rest it needs v_cmd = 0, so 3 e_v + xi_z alone must
# balance the weight, which puts the nominal xi_z at g m_obj / m0 (spec appendix "Payload-Aware Flight Control").
# ----------------------------------------------------------------------------------------------------------------------
PAYLOAD_STEADY_WINDOW_S = 5.0


def _hold_start_command(scn, t, p, memo) -> Command:
    start = memo.setdefault("start", p.copy())
    v = WAYPOINT_GAIN * (start - p)
    speed = np.linalg.norm(v)
    return (v * min(1.0, MAX_SPEED_MPS / speed) if speed > 0 else v), 0.0


def _payload_metrics(tr: Trace, platform: PlatformSpec) -> dict:
    return {
        "xi_z_steady": M.mean_over_last(tr.t, tr.xi[:, 2], PAYLOAD_STEADY_WINDOW_S),
        "xi_z_nominal_theory": GRAVITY * tr.payload_kg / platform.total_mass_kg,
        "mass_hat_final_kg": float(tr.mass_hat[-1]),
        "payload_kg": tr.payload_kg,
        "grasp_held": bool(tr.is_grasped[1:].all()) if tr.is_grasped is not None else False,
        "max_drift_m": M.max_drift(tr.position),
        **_saturation_metrics(tr, platform),
    }


# ----------------------------------------------------------------------------------------------------------------------
# reference: the virtual-joint airframe against a free rigid body, same controller law and command sequence
# ----------------------------------------------------------------------------------------------------------------------
REFERENCE_SEQUENCE = (  # (start time s, velocity m/s, yaw rate rad/s)
    (0.0, (0.0, 0.0, 0.0), 0.0),
    (2.0, (0.6, 0.0, 0.0), 0.0),
    (6.0, (0.0, 0.4, 0.2), 0.5),
    (10.0, (-0.3, 0.0, -0.2), -1.0),
    (14.0, (0.3, -0.3, 0.0), 0.3),
    (18.0, (0.0, 0.0, 0.3), 0.0),
    (21.0, (-0.5, 0.2, -0.3), 0.8),
    (23.0, (0.0, 0.0, 0.0), 0.0),
)


def _reference_command(scn, t, p, memo) -> Command:
    current = REFERENCE_SEQUENCE[0]
    for entry in REFERENCE_SEQUENCE:
        if t >= entry[0]:
            current = entry
    return np.array(current[1]), current[2]


def _reference_metrics(tr: Trace, platform: PlatformSpec) -> dict:
    dev = np.linalg.norm((tr.position - tr.position[0]) - (tr.reference_position - tr.reference_position[0]), axis=-1)
    return {
        "max_deviation_m": float(dev.max()),
        "final_deviation_m": float(dev[-1]),
        "rms_deviation_m": float(np.sqrt(np.mean(dev**2))),
        "path_length_m": float(np.linalg.norm(np.diff(tr.position, axis=0), axis=-1).sum()),
        **_saturation_metrics(tr, platform),
    }


SCENARIOS: dict[str, Scenario] = {
    s.name: s
    for s in (
        Scenario("hover", "hold position with zero command", 25.0, _zero, _hover_metrics),
        Scenario(
            "step", "0.6 m/s velocity step at 1 s, 1 rad/s yaw-rate step at 10 s", 18.0, _step_command, _step_metrics,
            scene="empty",
        ),
        Scenario("square", "fly a 2 m waypoint square and hold", 60.0, _square_command, _square_metrics, done=_square_done),
        Scenario(
            "payload", "hold the start point holding an object (default 0.37 kg)", 25.0, _hold_start_command,
            _payload_metrics, default_payload_kg=0.37,
        ),
        Scenario(
            "reference", "virtual joints vs a free rigid body, 25 s command sequence", 25.0, _reference_command,
            _reference_metrics, scene="empty", reference_body=True,
        ),
    )
}


def get_scenario(name: str) -> Scenario:
    try:
        return SCENARIOS[name]
    except KeyError:
        raise ValueError(f"unknown scenario {name!r}; valid scenarios: {', '.join(SCENARIOS)}") from None
