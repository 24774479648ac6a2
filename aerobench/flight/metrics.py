"""Pure metric functions over recorded flight traces (numpy arrays sampled at the physics rate unless named)."""

from __future__ import annotations

import numpy as np


def max_drift(position: np.ndarray) -> float:
    """Largest distance from the first recorded position, m. `position`: (T, 3)."""
    return float(np.max(np.linalg.norm(position - position[0], axis=-1)))


def max_tilt_deg(tilt_cos: np.ndarray) -> float:
    """Largest angle between body z and vertical, degrees, from the recorded R[2, 2]."""
    return float(np.degrees(np.max(np.arccos(np.clip(tilt_cos, -1.0, 1.0)))))


def step_response(t: np.ndarray, y: np.ndarray, t_step: float, target: float, band: float = 0.05) -> dict[str, float]:
    """Overshoot (% of the step), 10-90% rise time and settling time into +-band*|target| after a step at `t_step`.

    `y` starts from 0 before the step. Settling time is the last time the response is outside the band (measured
    from the step); if it never settles, it is the length of the record after the step.
    """
    after = t >= t_step
    ts, ys = t[after] - t_step, y[after]
    sign = np.sign(target)
    rel = ys * sign / abs(target)
    overshoot = max(0.0, float(np.max(rel)) - 1.0) * 100.0
    rise_lo = ts[np.argmax(rel >= 0.1)] if np.any(rel >= 0.1) else np.nan
    rise_hi = ts[np.argmax(rel >= 0.9)] if np.any(rel >= 0.9) else np.nan
    outside = np.abs(rel - 1.0) > band
    settling = float(ts[np.nonzero(outside)[0][-1]]) if np.any(outside) else 0.0
    if np.any(outside) and np.nonzero(outside)[0][-1] == len(ts) - 1:
        settling = float(ts[-1])
    return {
        "overshoot_pct": overshoot,
        "rise_time_s": float(rise_hi - rise_lo),
        "settling_time_s": settling,
        "final_value": float(np.mean(ys[-max(1, len(ys) // 20):])),
    }


def mean_over_last(t: np.ndarray, y: np.ndarray, seconds: float) -> float:
    return float(np.mean(y[t >= t[-1] - seconds]))


def max_trajectory_deviation(p_a: np.ndarray, p_b: np.ndarray) -> float:
    """Largest distance between two trajectories, each relative to its own start, m."""
    return float(np.max(np.linalg.norm((p_a - p_a[0]) - (p_b - p_b[0]), axis=-1)))


def cross_track_error(position: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Distance of each point of `position` (T, 3) from the segment start-end."""
    d = end - start
    s = np.clip(((position - start) @ d) / max(float(d @ d), 1e-12), 0.0, 1.0)
    return np.linalg.norm(position - (start + s[:, None] * d), axis=-1)
