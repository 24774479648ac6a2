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


def _check_counts(successes: int, n: int) -> None:
    if n < 0 or not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n, got {successes} of {n}")
