"""Completion times with the time limit as censoring (no rclpy): Kaplan–Meier curves and log-rank
tests, via scipy (``scipy.stats.ecdf`` with ``CensoredData``, ``scipy.stats.logrank``).

A trial that reached the goal is an event at its completion time; one that ran out of time (or
was aborted) is *censored* at its duration: all we know is that the subject would have needed
longer. Taking those durations as completion times (or leaving the trials out) biases every
median toward the fast conditions' favour or against it; the Kaplan–Meier estimator uses them
as "at least this long". Assumptions, written out in the report: censoring unrelated to how fast
the subject would have been (a fixed time limit is), and independent trials — repeated trials
of one subject are not, so the log-rank p-values are descriptive when subjects repeat trials.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass
class KaplanMeier:
    times: np.ndarray            # [s] where the curve steps
    still_going: np.ndarray      # fraction of trials not yet at the goal just after each time
    low: np.ndarray              # 95 % pointwise confidence band (Greenwood, log-log)
    high: np.ndarray
    n: int
    events: int
    median_s: float              # time at which half reached the goal (NaN: not reached)


def censored(times: list[float], reached: list[bool]) -> stats.CensoredData:
    t = np.asarray(times, float)
    ok = np.asarray(reached, bool)
    return stats.CensoredData(uncensored=t[ok], right=t[~ok])


def kaplan_meier(times: list[float], reached: list[bool]) -> KaplanMeier:
    """Kaplan–Meier estimate of the fraction still not at the goal over time."""
    n, events = len(times), int(sum(bool(r) for r in reached))
    if n == 0:
        e = np.empty(0)
        return KaplanMeier(e, e, e, e, 0, 0, math.nan)
    if events == 0:                       # nothing reached: the curve stays at 1 until the last censoring
        t = np.array([max(times)])
        one = np.ones(1)
        return KaplanMeier(t, one, one, one, n, 0, math.nan)
    res = stats.ecdf(censored(times, reached)).sf
    with warnings.catch_warnings():       # the band is undefined where the curve is 0 or 1: NaN there
        warnings.simplefilter("ignore", RuntimeWarning)
        ci = res.confidence_interval(0.95, method="log-log")
    below = np.flatnonzero(res.probabilities <= 0.5)
    median = float(res.quantiles[below[0]]) if len(below) else math.nan
    return KaplanMeier(res.quantiles, res.probabilities, np.nan_to_num(ci.low.probabilities, nan=0.0),
                       np.nan_to_num(ci.high.probabilities, nan=1.0), n, events, median)


@dataclass
class LogRank:
    a: str
    b: str
    statistic: float
    p: float
    p_holm: float = math.nan
    note: str = ""


def logrank(a: str, times_a, reached_a, b: str, times_b, reached_b) -> LogRank:
    """Two-sided log-rank test of condition ``a`` against ``b`` (no test when neither reached the goal)."""
    if not any(reached_a) and not any(reached_b):
        return LogRank(a, b, math.nan, math.nan, note="no trial reached the goal in either condition")
    if not len(times_a) or not len(times_b):
        return LogRank(a, b, math.nan, math.nan, note="a condition without trials")
    res = stats.logrank(censored(times_a, reached_a), censored(times_b, reached_b))
    return LogRank(a, b, float(res.statistic), float(res.pvalue))
