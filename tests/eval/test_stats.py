import math

import pytest

from aerobench.eval.stats import (
    fisher_exact,
    format_rate,
    holm_adjusted,
    mcnemar_exact,
    paired_comparison,
    standard_error,
    wilson_interval,
)


def test_spec_cells():
    assert format_rate(1, 50) == "2.0 ± 2.0"
    assert format_rate(2, 30) == "6.7 ± 4.6"
    assert format_rate(49, 50) == "98.0 ± 2.0"
    assert format_rate(0, 50) == "0.0 ± 0.0"
    assert standard_error(25, 50) == pytest.approx(math.sqrt(0.25 / 50))


def test_wilson_known_values():
    # Wilson 95% for 8/10 is (0.490, 0.943); for 0/20 it is (0, 0.161)
    lo, hi = wilson_interval(8, 10)
    assert lo == pytest.approx(0.4902, abs=1e-3) and hi == pytest.approx(0.9433, abs=1e-3)
    lo, hi = wilson_interval(0, 20)
    assert lo == 0.0 and hi == pytest.approx(0.1611, abs=1e-3)
    assert wilson_interval(0, 0) == (0.0, 1.0)


def test_bad_counts():
    with pytest.raises(ValueError, match="successes <= n"):
        standard_error(5, 3)


def test_mcnemar_exact():
    assert mcnemar_exact(0, 0) == 1.0
    # 10 discordant pairs all one way: 2 * 0.5**10
    assert mcnemar_exact(10, 0) == pytest.approx(2 * 0.5**10)
    # 6 vs 2: 2 * P(X <= 2 | n=8, p=.5) = 2 * 37/256
    assert mcnemar_exact(6, 2) == pytest.approx(2 * 37 / 256)


def test_holm_adjusted_p_values():
    # sorted 0.005, 0.01, 0.03, 0.04 of m = 4: x4, x3, x2, x1 = 0.02, 0.03, 0.06, 0.04 -> made non-decreasing: 0.06
    assert holm_adjusted([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm_adjusted([0.5, 0.9]) == [1.0, 1.0] and holm_adjusted([]) == []


def test_fisher_exact_known_value():
    # the tea-tasting table [[3, 1], [1, 3]]: two-sided p = 0.4857
    assert fisher_exact(3, 4, 1, 4) == pytest.approx(0.4857, abs=1e-4)
    assert fisher_exact(10, 10, 0, 10) == pytest.approx(1.0825e-5, rel=1e-3)


def test_paired_comparison():
    a = {i: i < 8 for i in range(10)}
    b = {i: i < 2 for i in range(10)}
    cmp = paired_comparison(a, b)
    assert (cmp.n, cmp.both, cmp.only_a, cmp.only_b, cmp.neither) == (10, 2, 6, 0, 2)
    assert cmp.p_value == pytest.approx(2 * 0.5**6)
    with pytest.raises(ValueError, match="share no episode"):
        paired_comparison({1: True}, {2: True})
