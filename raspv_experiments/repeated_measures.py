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
- subjects missing a condition are left out of that measure (complete cases only);
- success with one trial per subject and condition is a paired binary outcome: Cochran's Q and
  exact McNemar tests instead (:mod:`raspv_experiments.paired_binary`).

With n subjects a two-sided Wilcoxon test cannot give p below 2 / 2ⁿ, so fewer than 6 subjects
can never reach p < 0.05: the report says so rather than showing bare p-values.

Effect sizes beside the p-values: **Kendall's W** for the Friedman test (χ² / (n (k − 1)): 0 no
agreement among subjects on the order of the conditions, 1 all rank them alike) and the
**matched-pairs rank-biserial r** for each pair ((T⁺ − T⁻) / (T⁺ + T⁻) over the non-zero
differences: +1 every subject higher in the first condition, −1 every subject lower); and a
**bootstrap 95 % confidence interval** of the median paired difference (``scipy.stats.bootstrap``,
BCa where it is defined, percentile otherwise, 9999 resamples of subjects, seeded: the same data
give the same interval). Tied data give no scipy warnings: what cannot be tested is a note.
"""
from __future__ import annotations

import math
import warnings
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
    "Only subjects with every condition enter a measure's tests (complete cases). Failed trials enter the "
    "completion-time medians at their duration (the time limit): those times are censored, not missing — the "
    "Kaplan–Meier curves and log-rank tests below treat them as such.",
    "Success with one trial per subject and condition (a paired 0/1 outcome): Cochran's Q across conditions and "
    "exact McNemar tests for pairs (discordant subjects), Holm-corrected, instead of Friedman and Wilcoxon.",
    "Effect sizes: Kendall's W (Friedman) and the matched-pairs rank-biserial r (Wilcoxon); 95 % confidence "
    "intervals of the median paired difference by bootstrapping subjects (seeded).",
]
BOOTSTRAP_RESAMPLES = 9999
BOOTSTRAP_SEED = 0


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
    rank_biserial: float = math.nan      # matched-pairs rank-biserial r of (a − b)
    ci_low: float = math.nan             # bootstrap 95 % CI of the median of (a − b)
    ci_high: float = math.nan


@dataclass
class MeasureTests:
    measure: str
    conditions: list[str]
    subjects: list[str]
    table: np.ndarray                    # (subjects, conditions) summaries, complete cases
    friedman_statistic: float = math.nan
    friedman_p: float = math.nan
    friedman_note: str = ""
    kendall_w: float = math.nan
    pairs: list[PairTest] = field(default_factory=list)
    note: str = ""
    binary: bool = False                 # a paired 0/1 outcome: Cochran's Q and McNemar (raspv_experiments.paired_binary)


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
    if proportion:
        from raspv_experiments.paired_binary import compare_binary, is_paired_binary

        if is_paired_binary(values, conditions):         # one 0/1 per subject and condition
            return compare_binary(measure, values, conditions)
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
        if np.all(np.ptp(table, axis=1) == 0):
            res.friedman_note = "all values tied within every subject: no test"
        else:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    f = stats.friedmanchisquare(*[table[:, j] for j in range(len(conditions))])
                res.friedman_statistic, res.friedman_p = float(f.statistic), float(f.pvalue)
                res.kendall_w = kendall_w(res.friedman_statistic, n, len(conditions))
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
                pair.rank_biserial, pair.ci_low, pair.ci_high = 0.0, 0.0, 0.0
            else:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    w = stats.wilcoxon(table[:, i], table[:, j], zero_method="wilcox", alternative="two-sided")
                pair.statistic, pair.p = float(w.statistic), float(w.pvalue)
                if any("ties" in str(c.message) or "zero" in str(c.message) for c in caught):
                    pair.note = "ties or zero differences: normal approximation"
                pair.rank_biserial = rank_biserial(d)
                pair.ci_low, pair.ci_high = bootstrap_median_ci(d)
            res.pairs.append(pair)
    for pair, adjusted in zip(res.pairs, holm([p.p for p in res.pairs])):
        pair.p_holm = adjusted
    if n < 6:
        res.note = (f"with {n} subjects a two-sided Wilcoxon test cannot give p < {2 / 2 ** n:.3g}: "
                    "these tests cannot show a difference at α = 0.05; the figures and medians are what to read")
    return res


def kendall_w(friedman_chi2: float, subjects: int, conditions: int) -> float:
    """Kendall's coefficient of concordance from the Friedman statistic."""
    return float(friedman_chi2 / (subjects * (conditions - 1))) if subjects and conditions > 1 else math.nan


def rank_biserial(differences: np.ndarray) -> float:
    """Matched-pairs rank-biserial r: (T⁺ − T⁻) / (T⁺ + T⁻) over the non-zero differences."""
    d = np.asarray(differences, float)
    d = d[d != 0]
    if not len(d):
        return 0.0
    ranks = stats.rankdata(np.abs(d))
    plus, minus = ranks[d > 0].sum(), ranks[d < 0].sum()
    return float((plus - minus) / (plus + minus))


def bootstrap_median_ci(differences: np.ndarray, confidence: float = 0.95) -> tuple[float, float]:
    """Bootstrap CI of the median paired difference (BCa, percentile where BCa is undefined); NaN
    for fewer than 3 subjects. Seeded: the same differences give the same interval."""
    d = np.asarray(differences, float)
    if len(d) < 3:
        return math.nan, math.nan
    if np.ptp(d) == 0:
        return float(d[0]), float(d[0])
    for method in ("BCa", "percentile"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ci = stats.bootstrap((d,), np.median, confidence_level=confidence, n_resamples=BOOTSTRAP_RESAMPLES,
                                 method=method, rng=np.random.default_rng(BOOTSTRAP_SEED)).confidence_interval
        if np.isfinite(ci.low) and np.isfinite(ci.high):
            return float(ci.low), float(ci.high)
    return math.nan, math.nan


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a proportion (scipy's binomtest)."""
    if trials == 0:
        return (math.nan, math.nan)
    ci = stats.binomtest(successes, trials).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)
