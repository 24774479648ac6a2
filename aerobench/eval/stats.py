"""Success-rate statistics: binomial standard error, Wilson interval, and paired comparisons of two policies.

The spec reports each skill-object cell as "success % +- binomial standard error", SE = sqrt(p (1 - p) / n)
("Downstream Policy Benchmarking"); 1 of 50 is 2.0 +- 2.0 and 2 of 30 is 6.7 +- 4.6.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Z_95 = 1.959963984540054  # two-sided 95% normal quantile


def standard_error(successes: int, n: int) -> float:
    """Binomial standard error of the success fraction, sqrt(p (1 - p) / n); 0 for n = 0."""
    _check_counts(successes, n)
    if n == 0:
        return 0.0
    p = successes / n
    return math.sqrt(p * (1.0 - p) / n)


def wilson_interval(successes: int, n: int, z: float = Z_95) -> tuple[float, float]:
    """Wilson score interval of the success fraction (stays inside [0, 1] and is sane at 0 or n successes)."""
    _check_counts(successes, n)
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def format_rate(successes: int, n: int, digits: int = 1) -> str:
    """ "p +- se" in percent, the spec's cell format."""
    p = 100.0 * successes / n if n else 0.0
    return f"{p:.{digits}f} ± {100.0 * standard_error(successes, n):.{digits}f}"


def _binomial_pmf(k: int, n: int, p: float) -> float:
    return math.comb(n, k) * p**k * (1 - p) ** (n - k)


def mcnemar_exact(only_a: int, only_b: int) -> float:
    """Two-sided exact McNemar p-value from the discordant pairs (A succeeded alone, B succeeded alone)."""
    n = only_a + only_b
    if n == 0:
        return 1.0
    k = min(only_a, only_b)
    tail = sum(_binomial_pmf(i, n, 0.5) for i in range(k + 1))
    return min(1.0, 2.0 * tail)


def fisher_exact(a_success: int, a_n: int, b_success: int, b_n: int) -> float:
    """Two-sided Fisher exact p-value for two independent success counts (sums tables no more likely than observed)."""
    _check_counts(a_success, a_n)
    _check_counts(b_success, b_n)
    total_success, total = a_success + b_success, a_n + b_n

    def prob(k: int) -> float:  # hypergeometric: k of A's a_n draws are successes
        return math.comb(total_success, k) * math.comb(total - total_success, a_n - k) / math.comb(total, a_n)

    observed = prob(a_success)
    lo, hi = max(0, a_n - (total - total_success)), min(a_n, total_success)
    return min(1.0, sum(p for k in range(lo, hi + 1) if (p := prob(k)) <= observed * (1 + 1e-9)))


@dataclass(frozen=True)
class PairedComparison:
    """Two policies on the same episodes (same seeds): who won where, and the exact McNemar p-value."""

    n: int
    both: int
    only_a: int
    only_b: int
    neither: int
    p_value: float
    test: str = "exact McNemar"


def paired_comparison(a: dict, b: dict) -> PairedComparison:
    """Compare per-episode successes `{episode key: bool}` of two policies on their shared keys."""
    shared = sorted(set(a) & set(b))
    if not shared:
        raise ValueError("the two runs share no episode (same setting, skills, objects and seeds are needed)")
    both = sum(1 for k in shared if a[k] and b[k])
    only_a = sum(1 for k in shared if a[k] and not b[k])
    only_b = sum(1 for k in shared if b[k] and not a[k])
    return PairedComparison(len(shared), both, only_a, only_b, len(shared) - both - only_a - only_b,
                            mcnemar_exact(only_a, only_b))


def paired_difference_interval(both: int, only_a: int, only_b: int, neither: int, z: float = Z_95) -> tuple[float, float]:
    """95% interval for rate(A) - rate(B) on paired episodes: Newcombe (1998, Stat. Med. 17:2635) method 10, the
    Wilson score intervals of the two rates combined through the phi correlation of the 2x2 table (phi with the
    continuity correction of Newcombe's method as given in Altman et al., "Statistics with Confidence", 2000)."""
    for v in (both, only_a, only_b, neither):
        if v < 0:
            raise ValueError(f"paired counts must not be negative, got {both, only_a, only_b, neither}")
    n = both + only_a + only_b + neither
    if n == 0:
        return (-1.0, 1.0)
    p1, p2 = (both + only_a) / n, (both + only_b) / n
    l1, u1 = wilson_interval(both + only_a, n, z)
    l2, u2 = wilson_interval(both + only_b, n, z)
    margins = (both + only_a) * (only_b + neither) * (both + only_b) * (only_a + neither)
    phi = 0.0
    if margins > 0:
        cross = both * neither - only_a * only_b
        corrected = cross - n / 2 if cross > n / 2 else (cross if cross < 0 else 0.0)
        phi = corrected / math.sqrt(margins)
    d = p1 - p2
    lower = d - math.sqrt(max(0.0, (p1 - l1) ** 2 - 2 * phi * (p1 - l1) * (u2 - p2) + (u2 - p2) ** 2))
    upper = d + math.sqrt(max(0.0, (p2 - l2) ** 2 - 2 * phi * (p2 - l2) * (u1 - p1) + (u1 - p1) ** 2))
    return max(-1.0, lower), min(1.0, upper)


def holm_adjusted(p_values: list[float]) -> list[float]:
    """Holm's (1979) step-down adjusted p-values, in the order given: the k-th smallest of m is multiplied by
    m - k + 1, then made non-decreasing; a cell differs at family-wise level alpha where its adjusted p < alpha."""
    order = sorted(range(len(p_values)), key=lambda i: p_values[i])
    adjusted, running = [1.0] * len(p_values), 0.0
    for k, i in enumerate(order):
        running = max(running, min(1.0, (len(p_values) - k) * p_values[i]))
        adjusted[i] = running
    return adjusted


def mcnemar_power(n: int, discordant: float, difference: float, alpha: float = 0.05) -> float:
    """Approximate power of the two-sided McNemar test with `n` paired episodes to detect a true difference in
    success rate `difference`, when a fraction `discordant` of the pairs disagree (Connor, 1987, Biometrics 43:207)."""
    if n <= 0 or discordant <= 0 or difference == 0:
        return 0.0
    discordant = max(discordant, abs(difference))
    z_a = _normal_quantile(1 - alpha / 2)
    spread = math.sqrt(max(discordant - difference**2, 1e-12))
    z = (abs(difference) * math.sqrt(n) - z_a * math.sqrt(discordant)) / spread
    return 0.5 * (1 + math.erf(z / math.sqrt(2)))


def mcnemar_sample_size(discordant: float, difference: float, power: float = 0.8, alpha: float = 0.05) -> int:
    """Paired episodes the McNemar test needs to detect `difference` with `power` (Connor, 1987)."""
    discordant = max(discordant, abs(difference))
    z_a, z_b = _normal_quantile(1 - alpha / 2), _normal_quantile(power)
    n = (z_a * math.sqrt(discordant) + z_b * math.sqrt(max(discordant - difference**2, 0.0))) ** 2 / difference**2
    return math.ceil(n)


def _normal_quantile(q: float) -> float:
    """Inverse of the standard normal CDF (bisection on erf: exact enough for interval and power work)."""
    lo, hi = -10.0, 10.0
    for _ in range(100):
        mid = (lo + hi) / 2
        if 0.5 * (1 + math.erf(mid / math.sqrt(2))) < q:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


def _check_counts(successes: int, n: int) -> None:
    if n < 0 or not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n, got {successes} of {n}")
