"""Is a measure monotone over an ordered factor (e.g. phosphene count), and where does it level
off? (no rclpy)

For a within-subject sweep (every subject at every level), per measure:

- **Page's L test** (:func:`scipy.stats.page_trend_test`, asymptotic p: ties are frequent — a
  success rate of 1 at several levels) of the ordered alternative that the measure improves with
  the level — success rises, completion time (a trial cut off counted at the limit) and
  collisions fall — against no difference;
- each **step between adjacent levels**: the mean paired difference over subjects with a
  percentile-bootstrap 95 % CI (9999 resamples, seeded): a step whose CI excludes 0 is a change,
  and the level after the last such step is where the measure **levels off** (saturation) —
  within the sweep's power; more subjects narrow the intervals.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raspv_experiments.quick_sweep import bootstrap_mean_ci, measure_of

MEASURES = (("success", +1), ("time_s", -1), ("collisions", -1))      # name, the direction that is better


@dataclass
class Step:
    low: str
    high: str
    mean_difference: float               # high − low, mean over subjects
    ci: tuple[float, float]              # percentile bootstrap 95 %


@dataclass
class Trend:
    measure: str
    better: int                          # +1: higher is better, −1: lower
    levels: list[str]
    means: list[float]
    page_l: float
    page_p: float                        # one-sided, for improvement with the level
    steps: list[Step]

    @property
    def levels_off_at(self) -> str:
        """The level after the last adjacent step whose CI excludes 0 (the first level when none does)."""
        changed = [i for i, s in enumerate(self.steps) if s.ci[0] > 0 or s.ci[1] < 0]
        return self.levels[changed[-1] + 1] if changed else self.levels[0]


def subject_matrix(records, time_limits: dict[str, float], factor: str, levels: list[str], measure: str
                   ) -> tuple[list[int], np.ndarray]:
    """(subjects, (S, L) array): each subject's mean of ``measure`` at each level; subjects
    missing a level are left out (the test is within-subject)."""
    subjects = sorted({r.subject for r in records})
    rows, kept = [], []
    for s in subjects:
        row = []
        for level in levels:
            vals = [measure_of(r, measure, time_limits) for r in records
                    if r.subject == s and str(r.factors.get(factor, r.condition)) == level]
            row.append(np.mean(vals) if vals else np.nan)
        if np.isfinite(row).all():
            rows.append(row)
            kept.append(s)
    return kept, np.array(rows, float).reshape(len(rows), len(levels))


def ordered_trends(records, time_limits: dict[str, float], factor: str, levels: list[str]) -> list[Trend]:
    """A :class:`Trend` per measure over ``levels`` (in their order) of ``factor``."""
    from scipy import stats

    if len(levels) < 3:
        raise ValueError(f"a trend needs at least 3 ordered levels, got {levels}")
    out = []
    for k, (measure, better) in enumerate(MEASURES):
        subjects, m = subject_matrix(records, time_limits, factor, levels, measure)
        if len(subjects) < 2:
            raise ValueError(f"a trend needs at least 2 subjects with every level of {factor}, got {len(subjects)}")
        oriented = better * m
        if np.all(oriented == oriented[:, :1]):          # no differences at all: no evidence of a trend
            page_l, page_p = float("nan"), 1.0
        else:
            res = stats.page_trend_test(oriented, method="asymptotic")
            page_l, page_p = float(res.statistic), float(res.pvalue)
        steps = [Step(levels[i], levels[i + 1], float(np.mean(m[:, i + 1] - m[:, i])),
                      bootstrap_mean_ci(m[:, i + 1] - m[:, i], seed=100 * k + i + 1)) for i in range(len(levels) - 1)]
        out.append(Trend(measure, better, list(levels), [float(v) for v in m.mean(axis=0)], page_l, page_p, steps))
    return out


def trend_table(trends: list[Trend], factor: str) -> str:
    """Markdown: per measure, Page's test and each adjacent step with its CI."""
    lines = [f"| measure (better) | Page's L, p (improves with {factor}) | "
             + " | ".join(f"{s.low} → {s.high} [95 % CI]" for s in trends[0].steps) + " | levels off at |",
             "|---|---|" + "---|" * len(trends[0].steps) + "---|"]
    unit = {"success": 100.0, "time_s": 1.0, "collisions": 1.0}
    for t in trends:
        u = unit[t.measure]
        fmt = "{:+.0f}" if t.measure == "success" else "{:+.1f}"
        cells = [f"{fmt.format(u * s.mean_difference)} [{fmt.format(u * s.ci[0])}, {fmt.format(u * s.ci[1])}]"
                 for s in t.steps]
        name = {"success": "success, points", "time_s": "time s", "collisions": "collisions"}[t.measure]
        lines.append(f"| {name} ({'higher' if t.better > 0 else 'lower'}) | {t.page_l:.0f}, p = {t.page_p:.2g} | "
                     + " | ".join(cells) + f" | {t.levels_off_at} |")
    return "\n".join(lines)
