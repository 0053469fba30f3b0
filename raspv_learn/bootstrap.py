"""The evaluation's statistics: a class IoU per row and seed from per-frame confusion matrices,
its mean over seeds, and a seeded percentile bootstrap over seeds and frames (numpy only).

Each resample draws the seeds with replacement and the test frames with replacement — one draw
of frames per resample, shared by every seed and every row (paired) — pools each (row, seed)'s
confusion over the frames drawn (a frame drawn k times counts k times), takes the IoU, and
averages it over the seeds drawn. The gain is the learned row minus the best hand-designed row;
in each resample the best one of that resample (so the CI carries the choice of the best mode).
"""
from __future__ import annotations

from dataclasses import dataclass

import warnings

import numpy as np

CLASS_INDEX = {"iou_floor": 0, "iou_wall": 1, "iou_obstacle": 2}


def class_counts(confusions: np.ndarray, metric: str) -> np.ndarray:
    """(..., F, 3, 3) confusions (true × predicted) → (..., F, 3) [tp, fp, fn] of the metric's class."""
    c = CLASS_INDEX[metric]
    m = np.asarray(confusions, np.int64)
    tp = m[..., c, c]
    return np.stack([tp, m[..., :, c].sum(-1) - tp, m[..., c, :].sum(-1) - tp], -1)


def iou_of(counts: np.ndarray) -> np.ndarray:
    """IoU of pooled [tp, fp, fn] (last axis); NaN where the class never occurs nor is predicted."""
    counts = np.asarray(counts, np.float64)
    denom = counts[..., 0] + counts[..., 1] + counts[..., 2]
    return np.divide(counts[..., 0], denom, out=np.full(denom.shape, np.nan), where=denom > 0)


@dataclass
class Interval:
    mean: float
    low: float
    high: float

    def points(self) -> "Interval":
        return Interval(100 * self.mean, 100 * self.low, 100 * self.high)


@dataclass
class Summary:
    rows: list[str]
    per_seed: np.ndarray               # (R, S) IoU of each row and seed over all frames
    rows_ci: dict[str, Interval]       # mean over seeds and its CI, per row
    best: str                          # best hand-designed row (highest mean over seeds)
    gain: Interval                     # learned − best hand-designed (IoU units)


def summarise(counts: np.ndarray, rows: list[str], learned: str, resamples: int, confidence: float,
              seed: int) -> Summary:
    """``counts`` (R, S, F, 3) [tp, fp, fn] per row, seed and test frame; ``learned`` the row
    whose gain over the best of the other rows is estimated."""
    counts = np.asarray(counts, np.float64)
    R, S, F, _ = counts.shape
    if learned not in rows or R < 2 or S < 1 or F < 1:
        raise ValueError(f"need the learned row and >= 1 other, >= 1 seed and frame (rows {rows}, shape {counts.shape})")
    li = rows.index(learned)
    hand = [i for i in range(R) if i != li]
    per_seed = iou_of(counts.sum(2))                                            # (R, S)
    mean = np.nanmean(per_seed, 1)
    best = hand[int(np.nanargmax(mean[hand]))]
    rng = np.random.default_rng(seed)
    alpha = (1 - confidence) / 2
    draws = []
    with warnings.catch_warnings():                       # NaN where the class is absent from a draw
        warnings.simplefilter("ignore", RuntimeWarning)
        for start in range(0, resamples, 1000):                                 # bounded memory
            b = min(1000, resamples - start)
            weights = rng.multinomial(F, np.full(F, 1.0 / F), size=b).astype(np.float64)  # (b, F) frame counts
            seeds = rng.integers(0, S, size=(b, S))                                        # (b, S) seeds drawn
            pooled = np.einsum("bf,rsfk->brsk", weights, counts)                           # (b, R, S, 3)
            iou = iou_of(pooled)                                                           # (b, R, S)
            drawn = np.take_along_axis(iou, seeds[:, None, :].repeat(R, 1), axis=2)
            draws.append(np.nanmean(drawn, 2))                                             # (b, R)
    means = np.concatenate(draws)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        gains = means[:, li] - np.nanmax(means[:, hand], 1)
    rows_ci = {r: Interval(float(mean[i]), *map(float, np.nanquantile(means[:, i], [alpha, 1 - alpha])))
               for i, r in enumerate(rows)}
    gain = Interval(float(mean[li] - mean[best]), *map(float, np.nanquantile(gains, [alpha, 1 - alpha])))
    return Summary(rows, per_seed, rows_ci, rows[best], gain)
