"""Statistics for repeated-measures designs (every subject does every condition), via scipy; no rclpy.

Per measure (completion time, collisions, path efficiency, success rate, …) each subject's
trials of a condition are summarised by their median (success: the fraction), giving one
subjects × conditions table. Then:

- **Friedman test** (``scipy.stats.friedmanchisquare``) across the conditions (≥ 3 of them):
  a rank test that needs no normality; assumes independent subjects and a measure that is at
  least ordinal; it tests whether some condition differs, not which;
- **pairwise Wilcoxon signed-rank tests** (``scipy.stats.wilcoxon``, two-sided; exact for small
  samples without ties) between every pair of conditions, with **Holm's correction** for the
  number of pairs; they assume the paired differences are symmetric about their median; pairs
  whose differences are all zero get no test;
- subjects missing a condition are left out of that measure (complete cases only).

With n subjects a two-sided Wilcoxon test cannot give p below 2 / 2ⁿ, so fewer than 6 subjects
can never reach p < 0.05: the report says so rather than showing bare p-values.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

ASSUMPTIONS = [
    "Repeated measures: every subject did every condition; subjects are independent of one another.",
    "Each subject's trials of a condition are summarised by their median (success: the fraction of trials that "
    "reached the goal); practice trials are left out.",
    "Friedman test across conditions (three or more): rank-based, no normality assumed; it says whether some "
    "condition differs, not which.",
    "Pairwise Wilcoxon signed-rank tests (two-sided, exact for small samples without ties), Holm-corrected for "
    "the number of pairs: they assume symmetric paired differences.",
    "Only subjects with every condition enter a measure's tests (complete cases). Failed trials enter "
    "completion time at their duration (the time limit): the time is censored, not missing.",
]


@dataclass
class PairTest:
    a: str
    b: str
    n: int
    median_difference: float            # median of (a − b) over subjects
    statistic: float
    p: float
    p_holm: float = math.nan
    note: str = ""


@dataclass
class MeasureTests:
    measure: str
    conditions: list[str]
    subjects: list[str]
    table: np.ndarray                    # (subjects, conditions) summaries, complete cases
    friedman_statistic: float = math.nan
    friedman_p: float = math.nan
    friedman_note: str = ""
    pairs: list[PairTest] = field(default_factory=list)
    note: str = ""


def holm(pvalues: list[float]) -> list[float]:
    """Holm–Bonferroni adjusted p-values (NaN entries stay NaN and are not counted)."""
    idx = [i for i, p in enumerate(pvalues) if not math.isnan(p)]
    m = len(idx)
    out = [math.nan] * len(pvalues)
    running = 0.0
    for rank, i in enumerate(sorted(idx, key=lambda i: pvalues[i])):
        running = max(running, min(1.0, (m - rank) * pvalues[i]))
        out[i] = running
    return out


def subject_table(values: dict[tuple[str, str], list[float]], conditions: list[str],
                  proportion: bool = False) -> tuple[list[str], np.ndarray]:
    """{(subject, condition): trial values} → (complete subjects, (subjects, conditions) medians or means)."""
    subjects = sorted({s for s, _ in values})
    rows, keep = [], []
    for s in subjects:
        row = []
        for c in conditions:
            v = [x for x in values.get((s, c), []) if not (isinstance(x, float) and math.isnan(x))]
            row.append(float(np.mean(v)) if proportion and v else float(np.median(v)) if v else math.nan)
        if not any(math.isnan(x) for x in row):
            rows.append(row)
            keep.append(s)
    return keep, np.array(rows, dtype=float).reshape(len(rows), len(conditions))


def compare_conditions(measure: str, values: dict[tuple[str, str], list[float]], conditions: list[str],
                 proportion: bool = False) -> MeasureTests:
    subjects, table = subject_table(values, conditions, proportion)
    res = MeasureTests(measure, conditions, subjects, table)
    n = len(subjects)
    if len(conditions) < 2:
        res.note = "one condition: nothing to compare"
        return res
    if n < 2:
        res.note = f"{n} subject{'s' if n != 1 else ''} with every condition: no test possible"
        return res
    if len(conditions) >= 3:
        try:
            f = stats.friedmanchisquare(*[table[:, j] for j in range(len(conditions))])
            res.friedman_statistic, res.friedman_p = float(f.statistic), float(f.pvalue)
        except ValueError as exc:
            res.friedman_note = str(exc)
        if math.isnan(res.friedman_p) and not res.friedman_note:
            res.friedman_note = "all values tied"
    else:
        res.friedman_note = "two conditions: the Wilcoxon test below is the comparison"
    for i in range(len(conditions)):
        for j in range(i + 1, len(conditions)):
            d = table[:, i] - table[:, j]
            pair = PairTest(conditions[i], conditions[j], n, float(np.median(d)), math.nan, math.nan)
            if np.allclose(d, 0.0):
                pair.note = "no difference in any subject"
            else:
                w = stats.wilcoxon(table[:, i], table[:, j], zero_method="wilcox", alternative="two-sided")
                pair.statistic, pair.p = float(w.statistic), float(w.pvalue)
            res.pairs.append(pair)
    for pair, adjusted in zip(res.pairs, holm([p.p for p in res.pairs])):
        pair.p_holm = adjusted
    if n < 6:
        res.note = (f"with {n} subjects a two-sided Wilcoxon test cannot give p < {2 / 2 ** n:.3g}: "
                    "these tests cannot show a difference at α = 0.05; the figures and medians are what to read")
    return res


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a proportion (scipy's binomtest)."""
    if trials == 0:
        return (math.nan, math.nan)
    ci = stats.binomtest(successes, trials).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)
