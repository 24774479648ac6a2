"""Trajectory metrics from the spec's "Evaluation of Data Generation Strategies" (diversity and execution time).

Successful approach segments (spawn -> within 5 cm of the planned grasp pose) are drawn in a start-normalized X-Z
frame: the grasp pose at the origin and every trajectory starting at (1, 1). On that frame:
- coverage: occupied 0.05 x 0.05 cells of the union of a set of paths;
- velocity-direction entropy: Shannon entropy (bits) of the X-Z velocity headings over 36 bins;
- deviation from the policy's own mean path: paths resampled by normalized time, mean distance to their mean;
each estimated on 200 random subsets of 80 episodes (mean and 95% percentile interval). Time to success is split
into approach, alignment, grasp, lift and hold from the episode's event times.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

CELL = 0.05
DIRECTION_BINS = 36
SUBSETS, SUBSET_SIZE = 200, 80
APPROACH_RADIUS_M = 0.05
PHASES = ("approach", "alignment", "grasp", "lift", "hold")


def normalize_path(positions: np.ndarray, grasp: np.ndarray) -> np.ndarray:
    """`(T, 3)` world positions -> `(T, 2)` start-normalized (X, Z): grasp at (0, 0), start at (1, 1).

    X is the horizontal distance along the start -> grasp direction over its initial value, Z the height above the
    grasp over its initial value.
    """
    positions, grasp = np.asarray(positions, float), np.asarray(grasp, float)
    offset = positions - grasp
    horizontal0 = offset[0, :2]
    reach = np.linalg.norm(horizontal0)
    if reach < 1e-6 or abs(offset[0, 2]) < 1e-6:
        raise ValueError("the path must start away from the grasp pose both horizontally and vertically")
    x = offset[:, :2] @ (horizontal0 / reach) / reach
    z = offset[:, 2] / offset[0, 2]
    return np.stack([x, z], axis=1)


def approach_segment(positions: np.ndarray, grasp: np.ndarray, radius: float = APPROACH_RADIUS_M) -> np.ndarray | None:
    """The path from spawn to the first sample within `radius` of the grasp point (None if never)."""
    positions = np.asarray(positions, float)
    close = np.flatnonzero(np.linalg.norm(positions - np.asarray(grasp, float), axis=1) <= radius)
    return positions[: close[0] + 1] if close.size else None


def coverage(paths: Sequence[np.ndarray], cell: float = CELL) -> int:
    """Number of distinct `cell` x `cell` cells the normalized paths pass through (densified to half a cell)."""
    occupied = set()
    for path in paths:
        path = np.asarray(path, float)
        if len(path) > 1:  # densify so a fast step does not skip cells
            steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
            n = max(int(np.ceil(steps.sum() / (cell / 2))), len(path))
            s = np.concatenate([[0], np.cumsum(steps)])
            if s[-1] > 0:
                u = np.linspace(0, s[-1], n)
                path = np.stack([np.interp(u, s, path[:, 0]), np.interp(u, s, path[:, 1])], axis=1)
        occupied.update(map(tuple, np.floor(path / cell).astype(int)))
    return len(occupied)


def direction_entropy(paths: Sequence[np.ndarray], bins: int = DIRECTION_BINS, min_step: float = 1e-4) -> float:
    """Entropy (bits) of the X-Z motion headings of all steps longer than `min_step`, over `bins` angle bins."""
    angles = []
    for path in paths:
        d = np.diff(np.asarray(path, float), axis=0)
        moving = np.linalg.norm(d, axis=1) > min_step
        angles.append(np.arctan2(d[moving, 1], d[moving, 0]))
    angles = np.concatenate(angles) if angles else np.zeros(0)
    if not angles.size:
        return 0.0
    counts, _ = np.histogram(angles, bins=bins, range=(-np.pi, np.pi))
    p = counts[counts > 0] / counts.sum()
    return float(-(p * np.log2(p)).sum())


def resample(path: np.ndarray, points: int = 50) -> np.ndarray:
    """The path at `points` evenly spaced normalized times."""
    path = np.asarray(path, float)
    t = np.linspace(0, 1, len(path))
    u = np.linspace(0, 1, points)
    return np.stack([np.interp(u, t, path[:, k]) for k in range(path.shape[1])], axis=1)


def mean_path_deviation(paths: Sequence[np.ndarray], points: int = 50) -> float:
    """Mean over paths and normalized times of the distance to the set's mean path."""
    stacked = np.stack([resample(p, points) for p in paths])
    return float(np.linalg.norm(stacked - stacked.mean(axis=0), axis=2).mean())


@dataclass(frozen=True)
class Estimate:
    mean: float
    low: float  # 2.5th percentile over subsets
    high: float  # 97.5th percentile

    def as_dict(self) -> dict:
        return {"mean": self.mean, "ci95": [self.low, self.high]}


def subset_estimate(
    paths: Sequence[np.ndarray],
    metric: Callable[[Sequence[np.ndarray]], float],
    subsets: int = SUBSETS,
    size: int = SUBSET_SIZE,
    seed: int = 0,
) -> Estimate:
    """The metric over `subsets` random subsets of `size` paths (all paths when fewer): mean and 95% interval."""
    if not paths:
        raise ValueError("no successful paths to measure")
    rng = np.random.default_rng(seed)
    size = min(size, len(paths))
    values = np.array([metric([paths[i] for i in rng.choice(len(paths), size, replace=False)]) for _ in range(subsets)])
    return Estimate(float(values.mean()), float(np.percentile(values, 2.5)), float(np.percentile(values, 97.5)))


def diversity(paths: Sequence[np.ndarray], seed: int = 0) -> dict:
    """Coverage, direction entropy and mean-path deviation of normalized approach paths (subset estimates)."""
    return {
        "episodes": len(paths),
        "subset_size": min(SUBSET_SIZE, len(paths)),
        "coverage_cells": subset_estimate(paths, coverage, seed=seed).as_dict(),
        "direction_entropy_bits": subset_estimate(paths, direction_entropy, seed=seed).as_dict(),
        "mean_path_deviation": subset_estimate(paths, mean_path_deviation, seed=seed).as_dict(),
    }


def phase_durations(boundaries: Sequence[float | None], dt: float) -> dict[str, float] | None:
    """Seconds in approach, alignment, grasp, lift and hold from the steps that end each phase.

    `boundaries`: the control steps at which approach, alignment, grasp, lift and hold end (the last one is the
    success step); a boundary that came earlier than the one before it adds no time (phases may overlap).
    None when the episode has no success step.
    """
    if len(boundaries) != len(PHASES):
        raise ValueError(f"need {len(PHASES)} phase boundaries ({', '.join(PHASES)}), got {len(boundaries)}")
    if boundaries[-1] is None:
        return None
    out, previous = {}, 0.0
    for phase, end in zip(PHASES, boundaries, strict=True):
        end = previous if end is None else max(float(end), previous)
        out[phase] = (end - previous) * dt
        previous = end
    return out


def mean_phase_durations(per_episode: Sequence[dict[str, float] | None]) -> dict[str, float]:
    """Mean seconds per phase over the successful episodes (and their total)."""
    done = [d for d in per_episode if d is not None]
    if not done:
        raise ValueError("no successful episode to time")
    means = {p: float(np.mean([d[p] for d in done])) for p in PHASES}
    means["total"] = float(sum(means.values()))
    return means
