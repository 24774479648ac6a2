import numpy as np
import pytest

from aerobench.eval.metrics import (
    approach_segment,
    coverage,
    direction_entropy,
    diversity,
    mean_path_deviation,
    mean_phase_durations,
    normalize_path,
    phase_durations,
    subset_estimate,
)


def _l_path(n=20):
    """The expert's L shape: fly level to above the object, then descend (start-normalized)."""
    level = np.stack([np.linspace(1, 0, n), np.ones(n)], 1)
    down = np.stack([np.zeros(n), np.linspace(1, 0, n)], 1)
    return np.concatenate([level, down[1:]])


def test_normalize_puts_start_at_one_one_and_grasp_at_origin():
    grasp = np.array([2.0, -1.0, 0.8])
    world = np.array([[2.6, -0.2, 1.4], [2.3, -0.6, 1.1], grasp])
    norm = normalize_path(world, grasp)
    assert norm[0] == pytest.approx([1, 1]) and norm[-1] == pytest.approx([0, 0]) and norm[1] == pytest.approx([0.5, 0.5])
    with pytest.raises(ValueError, match="start away"):
        normalize_path(np.array([[2.0, -1.0, 1.5]]), grasp)


def test_approach_segment_stops_within_five_centimetres():
    path = np.array([[1.0, 0, 1], [0.5, 0, 0.5], [0.04, 0, 0], [0, 0, 0]])
    assert len(approach_segment(path, np.zeros(3))) == 3
    assert approach_segment(path[:2], np.zeros(3)) is None


def test_coverage_counts_cells():
    # a straight diagonal from (1,1) to (0,0) crosses 20 diagonal cells (plus corner-touching neighbours)
    diag = np.stack([np.linspace(1, 0, 3)] * 2, 1)
    assert 20 <= coverage([diag]) <= 41
    # the L path: 20 cells along the top row and 20 down the left column, sharing the corner
    assert coverage([_l_path()]) in (40, 41, 42)
    assert coverage([_l_path(), _l_path()]) == coverage([_l_path()])  # same path twice covers nothing new


def test_direction_entropy():
    assert direction_entropy([np.stack([np.linspace(1, 0, 10), np.ones(10)], 1)]) == 0.0  # one heading
    assert direction_entropy([_l_path()]) == pytest.approx(1.0, abs=1e-9)  # two headings, equal time: 1 bit
    circle = np.stack([np.cos(np.linspace(0, 2 * np.pi, 3601)), np.sin(np.linspace(0, 2 * np.pi, 3601))], 1)
    assert direction_entropy([circle]) == pytest.approx(np.log2(36), abs=0.01)  # all 36 bins equally


def test_mean_path_deviation():
    assert mean_path_deviation([_l_path()] * 5) == pytest.approx(0.0)
    shifted = [_l_path() + [0, dz] for dz in (-0.1, 0.1)]
    assert mean_path_deviation(shifted) == pytest.approx(0.1)


def test_subset_estimates_are_seeded():
    rng = np.random.default_rng(1)
    paths = [_l_path() + rng.normal(0, 0.05, (39, 2)) for _ in range(100)]
    a, b = diversity(paths, seed=3), diversity(paths, seed=3)
    assert a == b and a["subset_size"] == 80
    est = subset_estimate(paths, coverage, subsets=20)
    assert est.low <= est.mean <= est.high


def test_phase_durations():
    d = phase_durations([100, 120, 150, 170, 180], dt=0.05)
    assert d == pytest.approx({"approach": 5.0, "alignment": 1.0, "grasp": 1.5, "lift": 1.0, "hold": 0.5})
    # alignment seen before the approach ended: no time in alignment, nothing negative
    d = phase_durations([100, 90, 150, None, 180], dt=0.05)
    assert d["alignment"] == 0.0 and d["lift"] == 0.0 and sum(d.values()) == pytest.approx(9.0)
    assert phase_durations([100, 120, None, None, None], dt=0.05) is None
    means = mean_phase_durations([phase_durations([20, 40, 60, 80, 100], 0.05), None])
    assert means["total"] == pytest.approx(5.0)
