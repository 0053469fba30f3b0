"""How many virtual subjects a within-subject comparison needs (no rclpy): the power of a paired
t-test, two-sided, from the noncentral t distribution (scipy) — the computation G*Power and
statsmodels' ``TTestPower`` do.

    paired_t_power(effect_size=0.5, n=34, alpha=0.05)      # 0.808 (G*Power: 0.8078)
    subjects_for_power(effect_size=0.5, power=0.8)         # 34

``effect_size`` is Cohen's d_z: the mean paired difference over the standard deviation of the
paired differences. The Wilcoxon signed-rank test a report runs has an asymptotic relative
efficiency of at least 0.864 against the t-test (0.955 for normal differences; Lehmann 1975), so
a Wilcoxon analysis needs up to 1/0.864 ≈ 1.16 times the n given here.
"""
from __future__ import annotations

import math

import numpy as np


def paired_t_power(effect_size: float, n: int, alpha: float = 0.05) -> float:
    """Power of a two-sided paired t-test at level ``alpha`` with ``n`` pairs for a true d_z
    ``effect_size`` (probability of p < alpha)."""
    from scipy import stats

    if n < 2:
        raise ValueError(f"a paired t-test needs at least 2 pairs, got {n}")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    df = n - 1
    critical = stats.t.ppf(1 - alpha / 2, df)
    nc = abs(effect_size) * math.sqrt(n)
    return float(stats.nct.sf(critical, df, nc) + stats.nct.cdf(-critical, df, nc))


def subjects_for_power(effect_size: float, power: float = 0.8, alpha: float = 0.05, most: int = 10_000) -> int:
    """The smallest n whose :func:`paired_t_power` reaches ``power``."""
    if effect_size == 0:
        raise ValueError("no n detects an effect of size 0")
    for n in range(2, most + 1):
        if paired_t_power(effect_size, n, alpha) >= power:
            return n
    raise ValueError(f"more than {most} subjects needed for d_z {effect_size}")


def effect_size_dz(differences) -> float:
    """Cohen's d_z of paired differences: their mean over their standard deviation (ddof 1)."""
    d = np.asarray(differences, float)
    if len(d) < 2 or d.std(ddof=1) == 0:
        raise ValueError("d_z needs at least 2 differences that are not all equal")
    return float(d.mean() / d.std(ddof=1))
