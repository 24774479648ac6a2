"""`aerobench plan`: the exact McNemar rejection region, the planned n checked by simulation, one-line refusals."""

from functools import cache

import numpy as np
import pytest

from aerobench.eval.plan import mcnemar_exact_power, plan, plan_one, rejection_counts
from aerobench.eval.stats import mcnemar_exact, mcnemar_sample_size
from tests.cli_here import aerobench_here


@cache
def _rejects(only_a: int, only_b: int, alpha: float) -> bool:
    return mcnemar_exact(only_a, only_b) < alpha  # what `aerobench compare` calls "A better" / "B better"


def _simulated_power(n: int, joint: tuple[float, float, float, float], alpha: float, reps: int = 4000,
                     seed: int = 0) -> float:
    """Share of `reps` simulated paired evaluations of n episodes (joint: both, A only, B only, neither) in which
    compare's exact McNemar test rejects."""
    counts = np.random.default_rng(seed).multinomial(n, joint, size=reps)
    return float(np.mean([_rejects(int(a), int(b), alpha) for _, a, b, _ in counts]))


def _mc_floor(power: float, reps: int = 4000) -> float:
    return power - 3 * np.sqrt(power * (1 - power) / reps)  # three Monte-Carlo standard errors


def test_rejection_region_is_the_exact_mcnemar_test():
    d = np.arange(120)
    for alpha in (0.05, 0.01, 0.05 / 8):
        c = rejection_counts(d, alpha)
        for dd in d:
            assert [k for k in range(dd + 1) if min(k, dd - k) <= c[dd]] == \
                   [k for k in range(dd + 1) if mcnemar_exact(k, dd - k) < alpha], (alpha, dd)


@pytest.mark.parametrize("baseline, difference", [(0.5, 0.2), (0.8, 0.1), (0.9, 0.1)])
def test_the_planned_n_has_the_power_it_claims(baseline, difference):
    """Simulated evaluations of the printed n (independent outcomes given the start, the default) reach 80% power;
    one episode fewer does not by the exact computation, and two thirds of n clearly does not."""
    for p in plan(baseline, difference):
        p0, p1 = p.baseline, p.alternative
        joint = (p0 * p1, p1 * (1 - p0), p0 * (1 - p1), (1 - p0) * (1 - p1))  # A at p1, B at p0
        assert p.power >= 0.8 > mcnemar_exact_power(p.n - 1, joint[1], joint[2])
        assert _simulated_power(p.n, joint, 0.05) >= _mc_floor(0.8)
        assert _simulated_power(2 * p.n // 3, joint, 0.05, seed=1) < 0.75
        # the exact test needs a little more than Connor's normal approximation, never much more
        assert mcnemar_sample_size(p.discordant, difference) <= p.n <= 1.2 * mcnemar_sample_size(p.discordant, difference)


def test_correlated_outcomes_and_several_cells():
    """A pilot's discordant share (policies failing on the same starts) lowers n; 8 cells at Holm's strictest step
    (alpha / 8) raise it, and the simulation at that level still reaches the power."""
    independent = plan_one(0.7, 0.8)
    correlated = plan_one(0.7, 0.8, discordant=0.14)  # A only 0.12, B only 0.02
    assert correlated.n < independent.n / 2 and correlated.discordant == 0.14
    assert _simulated_power(correlated.n, (0.68, 0.12, 0.02, 0.18), 0.05) >= _mc_floor(0.8)
    holm = plan(0.7, 0.1, cells=8, discordant=0.14)[0]
    assert holm.alpha == pytest.approx(0.05 / 8) and holm.n > correlated.n
    assert _simulated_power(holm.n, (0.68, 0.12, 0.02, 0.18), 0.05 / 8) >= _mc_floor(0.8)


def test_cli_prints_one_line_per_alternative_and_what_n_means():
    r = aerobench_here("plan", "--baseline", "0.5", "--difference", "0.2")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert "exact McNemar" in lines[0] and "80% power" in lines[0]
    assert lines[1].startswith("  50% vs 70%: n = 103 episodes per cell")
    assert lines[2].startswith("  50% vs 30%: n = 103 episodes per cell")
    assert lines[3].startswith("n: episodes per skill-object cell")
    one_sided = aerobench_here("plan", "--baseline", "0.95", "--difference", "0.05").stdout
    assert "95% vs 100%" in one_sided and "95% vs 90%" in one_sided
    assert "over 4 cells" in aerobench_here("plan", "--baseline", "0.5", "--difference", "0.2", "--cells", "4").stdout


@pytest.mark.parametrize("args, message", [
    (["--baseline", "1.2", "--difference", "0.1"], "--baseline must be between 0 and 1 (exclusive), got 1.2"),
    (["--baseline", "0", "--difference", "0.1"], "--baseline must be between 0 and 1 (exclusive), got 0"),
    (["--baseline", "0.5", "--difference", "-0.1"], "--difference must be between 0 and 1 (exclusive), got -0.1"),
    (["--baseline", "0.95", "--difference", "0.1"], "--baseline 0.95 + --difference 0.1 is above 1"),
    (["--baseline", "0.5", "--difference", "0.1", "--power", "1"], "--power must be between 0 and 1"),
    (["--baseline", "0.5", "--difference", "0.1", "--alpha", "nan"], "--alpha must be between 0 and 1"),
    (["--baseline", "0.5", "--difference", "0.1", "--cells", "0"], "--cells must be a positive integer, got 0"),
    (["--baseline", "0.5", "--difference", "0.1", "--discordant", "0.05"], "--discordant 0.05 is impossible"),
])
def test_bad_input_is_one_line(args, message):
    r = aerobench_here("plan", *args)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.startswith(f"aerobench plan: error: {message}") and r.stderr.count("\n") == 1, r.stderr
