"""`aerobench plan`: how many episodes per cell an evaluation needs to detect a given success-rate difference.

Sized for the test `aerobench compare` runs: two policies evaluated on the same starts (one `--seed`), their outcomes
paired episode by episode, the exact two-sided McNemar test on the discordant pairs. Its power at n paired episodes is
computed exactly, not from a normal approximation: the number of discordant pairs D is Binomial(n, psi), and given D = d
the pairs that only A won are Binomial(d, only_a / psi); the test rejects where its p-value (`stats.mcnemar_exact`) is
below alpha. The planned n is the smallest from which the power stays at or above the target (the exact test's power
is slightly saw-toothed in n). psi, the share of discordant pairs, is what the paired design gains from: by default the
two policies' outcomes are taken as independent given the start (psi = p0 (1 - p1) + p1 (1 - p0)); policies that fail
on the same hard starts disagree less and need fewer episodes, and `discordant` sets psi from a pilot comparison.
Across several cells, the Holm procedure's strictest step compares the smallest p-value with alpha / cells; sizing each
cell at that (Bonferroni) level gives every cell at least the target power under Holm too.
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass

import numpy as np
from scipy.stats import binom

from .stats import mcnemar_sample_size

WINDOW = 20  # sizes above the bisected crossing checked for a dip below the target power


@dataclass(frozen=True)
class Plan:
    """Episodes per cell to tell `alternative` from `baseline` with `power` (exact McNemar, paired)."""

    baseline: float
    alternative: float
    n: int
    power: float  # exact power at n
    discordant: float  # share of pairs one policy wins and the other loses
    alpha: float  # per cell (alpha / cells)


def rejection_counts(d: np.ndarray, alpha: float) -> np.ndarray:
    """Per number of discordant pairs d, the largest count c such that the exact McNemar test rejects when
    min(only A, only B) <= c (2 P(X <= c) < alpha, X ~ Bin(d, 1/2)); -1 where no split of d pairs is significant."""
    c = binom.ppf(alpha / 2, d, 0.5).astype(int) - 1  # ppf: the smallest k with P(X <= k) >= alpha / 2
    ok = binom.cdf(c + 1, d, 0.5) < alpha / 2  # ppf's own rounding at an exact tie
    return np.where(ok, c + 1, c)


def mcnemar_exact_power(n: int, only_a: float, only_b: float, alpha: float = 0.05) -> float:
    """Power of the two-sided exact McNemar test on n paired episodes, where a pair is won by A alone with probability
    `only_a` and by B alone with `only_b`."""
    psi = only_a + only_b
    if n <= 0 or psi <= 0:
        return 0.0
    d = np.arange(n + 1)
    c = rejection_counts(d, alpha)
    q = only_a / psi
    reject = np.where(c >= 0, binom.cdf(c, d, q) + binom.sf(d - c - 1, d, q), 0.0)
    return float(np.clip(np.sum(binom.pmf(d, n, psi) * reject), 0.0, 1.0))


def _split(baseline: float, alternative: float, discordant: float | None) -> tuple[float, float, float]:
    """(A alone, B alone, psi) for A at `alternative` and B at `baseline`."""
    if discordant is None:
        only_a, only_b = alternative * (1 - baseline), baseline * (1 - alternative)
        return only_a, only_b, only_a + only_b
    delta = alternative - baseline
    only_a, only_b = (discordant + delta) / 2, (discordant - delta) / 2
    both = alternative - only_a
    if min(only_a, only_b, both, 1 - both - only_a - only_b) < -1e-12:
        raise ValueError(f"--discordant {discordant} is impossible for rates {baseline:g} and {alternative:g} "
                         f"(it must be between |difference| = {abs(delta):g} and "
                         f"{min(alternative + baseline, 2 - alternative - baseline):g})")
    return only_a, only_b, discordant


def plan_one(baseline: float, alternative: float, power: float = 0.8, alpha: float = 0.05,
             discordant: float | None = None) -> Plan:
    """The smallest n from which the exact McNemar power against `alternative` stays at least `power`."""
    only_a, only_b, psi = _split(baseline, alternative, discordant)

    def power_at(n: int) -> float:
        return mcnemar_exact_power(n, only_a, only_b, alpha)

    hi = max(2, mcnemar_sample_size(psi, abs(alternative - baseline), power, alpha))  # Connor (1987), a start
    while power_at(hi) < power:
        hi *= 2
    lo = 1
    while hi - lo > 1:  # bisection as if power rose with n; the window below catches its saw teeth
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if power_at(mid) < power else (lo, mid)
    top = hi + WINDOW
    while power_at(top) < power:
        top += WINDOW
    n = next(m + 1 for m in range(top, 0, -1) if power_at(m) < power) if power_at(1) < power else 1
    return Plan(baseline, alternative, n, power_at(n), psi, alpha)


def plan(baseline: float, difference: float, power: float = 0.8, alpha: float = 0.05, cells: int = 1,
         discordant: float | None = None) -> list[Plan]:
    """Episodes per cell against each alternative rate baseline +- difference that lies in [0, 1] (two-sided test),
    at alpha / cells per cell."""
    for name, value in (("--baseline", baseline), ("--difference", difference), ("--power", power), ("--alpha", alpha)):
        if not (math.isfinite(value) and 0 < value < 1):
            raise ValueError(f"{name} must be between 0 and 1 (exclusive), got {value:g}")
    if baseline + difference > 1 + 1e-12:  # 0.7 + 0.3 may round above 1
        raise ValueError(f"--baseline {baseline:g} + --difference {difference:g} is above 1: no success rate to detect")
    if not isinstance(cells, int) or cells < 1:
        raise ValueError(f"--cells must be a positive integer, got {cells}")
    if discordant is not None and not (math.isfinite(discordant) and 0 < discordant <= 1):
        raise ValueError(f"--discordant must be between 0 and 1, got {discordant:g}")
    alternatives = [min(1.0, baseline + difference)] + ([max(0.0, baseline - difference)] if baseline - difference > -1e-12 else [])
    return [plan_one(baseline, a, power, alpha / cells, discordant) for a in alternatives]


def format_plan(plans: list[Plan], power: float, alpha: float, cells: int, discordant: float | None) -> str:
    level = f"alpha {alpha:g} two-sided" if cells == 1 else (
        f"alpha {alpha:g} two-sided over {cells} cells: {alpha / cells:.3g} per cell (Holm's strictest step)")
    lines = [f"exact McNemar test on paired episodes (aerobench compare), {level}, {100 * power:g}% power:"]
    for p in plans:
        lines.append(f"  {100 * p.baseline:g}% vs {100 * p.alternative:g}%: n = {p.n} episodes per cell "
                     f"(power {100 * p.power:.1f}%, {100 * p.discordant:.1f}% of pairs discordant)")
    shares = ("the two policies' outcomes taken as independent given the start; policies that fail on the same starts "
              "disagree less and need fewer (--discordant sets the share from a pilot compare)") if discordant is None \
        else f"a share of {discordant:g} of the pairs discordant, as given"
    lines.append(textwrap.fill(f"n: episodes per skill-object cell for each policy (aerobench eval --episodes-per-object "
                               f"n), both evaluated with the same --seed so that compare pairs them; starts rejected at "
                               f"initialization come on top; {shares}.", width=118))
    return "\n".join(lines)
