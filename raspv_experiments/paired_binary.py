"""Tests for paired binary outcomes (reached the goal or not), via scipy; no rclpy.

When every subject did each condition once, success is one 0/1 per subject and condition — a
paired binary outcome, for which the rank tests of :mod:`raspv_experiments.repeated_measures`
(Friedman, Wilcoxon on 0/1 differences) are not the tests to use. Then:

- **Cochran's Q** across the conditions (≥ 3): Q = (k − 1)(k Σ C_j² − N²) / (k N − Σ R_i²) with
  column totals C_j, row totals R_i and N successes in all, χ² with k − 1 degrees of freedom
  (Cochran 1950); subjects who succeeded or failed everywhere carry no information and cancel;
- **McNemar's exact test** for each pair: the subjects who succeeded in one condition only
  (b in the first, c in the second) — under no difference each such subject is a fair coin, so
  p is the two-sided binomial test of b of b + c at 0.5 (``scipy.stats.binomtest``), Holm-corrected
  over the pairs; the effect is the difference of the success proportions with a 95 % bootstrap
  interval over subjects (seeded).
"""
from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import stats

from raspv_experiments.repeated_measures import (BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED, MeasureTests, PairTest,
                                                 holm, subject_table)


def is_paired_binary(values: dict[tuple[str, str], list[float]], conditions: list[str]) -> bool:
    """Every (subject, condition) cell present holds exactly one 0/1 value."""
    cells = [v for (_, c), v in values.items() if c in conditions]
    return bool(cells) and all(len(v) == 1 and v[0] in (0.0, 1.0) for v in cells)


def cochran_q(table: np.ndarray) -> tuple[float, float]:
    """(Q, p) of Cochran's Q test on a (subjects, conditions) 0/1 table; NaN when no subject's
    outcome differs between conditions."""
    x = np.asarray(table, float)
    k = x.shape[1]
    rows, cols, total = x.sum(axis=1), x.sum(axis=0), x.sum()
    denominator = k * total - float((rows ** 2).sum())
    if k < 2 or denominator == 0:
        return math.nan, math.nan
    q = (k - 1) * (k * float((cols ** 2).sum()) - total ** 2) / denominator
    return float(q), float(stats.chi2.sf(q, k - 1))


def mcnemar_exact(a: np.ndarray, b: np.ndarray) -> tuple[int, int, float]:
    """(subjects who succeeded only in a, only in b, exact two-sided p); p NaN with no such subject."""
    only_a, only_b = int(np.sum((a == 1) & (b == 0))), int(np.sum((a == 0) & (b == 1)))
    if only_a + only_b == 0:
        return only_a, only_b, math.nan
    return only_a, only_b, float(stats.binomtest(only_a, only_a + only_b, 0.5).pvalue)


def _difference_ci(d: np.ndarray) -> tuple[float, float]:
    if len(d) < 3:
        return math.nan, math.nan
    if np.ptp(d) == 0:
        return float(d[0]), float(d[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ci = stats.bootstrap((d,), np.mean, confidence_level=0.95, n_resamples=BOOTSTRAP_RESAMPLES,
                             method="percentile", rng=np.random.default_rng(BOOTSTRAP_SEED)).confidence_interval
    return float(ci.low), float(ci.high)


def compare_binary(measure: str, values: dict[tuple[str, str], list[float]], conditions: list[str]) -> MeasureTests:
    """Cochran's Q (≥ 3 conditions) and pairwise exact McNemar tests of a paired 0/1 outcome."""
    subjects, table = subject_table(values, conditions, proportion=True)
    res = MeasureTests(measure, conditions, subjects, table, binary=True)
    if len(conditions) < 2 or len(subjects) < 2:
        res.note = "one condition: nothing to compare" if len(conditions) < 2 else "fewer than 2 subjects: no test"
        return res
    if len(conditions) >= 3:
        res.friedman_statistic, res.friedman_p = cochran_q(table)
        if math.isnan(res.friedman_p):
            res.friedman_note = "no subject's outcome differs between conditions: no test"
    else:
        res.friedman_note = "two conditions: McNemar's test below is the comparison"
    for i in range(len(conditions)):
        for j in range(i + 1, len(conditions)):
            only_a, only_b, p = mcnemar_exact(table[:, i], table[:, j])
            d = table[:, i] - table[:, j]
            pair = PairTest(conditions[i], conditions[j], len(subjects), float(d.mean()), float(min(only_a, only_b)), p,
                            note=f"discordant subjects: {only_a} succeeded only in {conditions[i]}, {only_b} only in "
                                 f"{conditions[j]}")
            pair.ci_low, pair.ci_high = _difference_ci(d)
            res.pairs.append(pair)
    for pair, adjusted in zip(res.pairs, holm([p.p for p in res.pairs])):
        pair.p_holm = adjusted
    return res
