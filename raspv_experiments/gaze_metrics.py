"""Per-trial eye-gaze metrics from a gaze trace (no rclpy): fixations, saccades, validity.

A trace is the samples of ``/gaze/direction`` a trial logged (``gaze.csv`` of the simulator's
run log, :func:`raspv_sim.experiment_log.read_gaze`): sample times [s] (the sender's own
intervals), unit directions in the head frame and a validity flag. Samples are classified by
velocity (I-VT, Salvucci & Goldberg 2000): between two successive valid samples at most
:data:`MAX_GAP_S` apart the angular velocity is the angle over the interval; above the threshold
(30°/s, Tobii's I-VT default, Olsen 2012; the spv node's :data:`raspv_spv.gaze.SACCADE_THRESHOLD_DEG_S`)
the interval belongs to a saccade. Consecutive saccade intervals are one saccade; its amplitude
is the angle from where it started to where it ended. The stretches between saccades (and
invalid samples, and gaps) are fixations when they last at least :data:`MIN_FIXATION_S`
(60 ms, Olsen 2012's "discard short fixations").

- **fixation count**, and their mean duration [s];
- **saccade count** and **mean saccade amplitude** [deg] (NaN without saccades);
- **valid share**: the share of the trial's time covered by valid samples (each sample covers
  the interval to the next, at most :data:`MAX_GAP_S`; NaN without samples).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from raspv_spv.gaze import SACCADE_THRESHOLD_DEG_S

MAX_GAP_S = 0.1           # successive samples further apart give no velocity (a gap) [s]
MIN_FIXATION_S = 0.06     # shorter stretches between saccades are not counted as fixations [s]


@dataclass
class GazeMetrics:
    samples: int
    valid_share: float                 # 0..1 of the trial's time (NaN: no samples)
    fixations: int
    mean_fixation_s: float             # NaN without fixations
    saccades: int
    mean_saccade_amplitude_deg: float  # NaN without saccades

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles between row vectors [deg] (atan2 of |a×b| and a·b: exact for small angles)."""
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b)))


def gaze_metrics(t: np.ndarray, directions: np.ndarray, valid: np.ndarray,
                 threshold_deg_s: float = SACCADE_THRESHOLD_DEG_S) -> GazeMetrics:
    """Metrics of a trace: ``t`` (N,) [s] increasing, ``directions`` (N, 3) unit (head frame; rows
    of invalid samples are ignored), ``valid`` (N,) bool."""
    t = np.asarray(t, float)
    n = len(t)
    if n == 0:
        return GazeMetrics(0, math.nan, 0, math.nan, 0, math.nan)
    valid = np.asarray(valid, bool)
    d = np.nan_to_num(np.asarray(directions, float).reshape(n, 3))
    dt = np.diff(t)
    cover = np.minimum(np.append(dt, np.median(dt) if n > 1 else 0.0), MAX_GAP_S)
    total = float(cover.sum())
    valid_share = float(cover[valid].sum() / total) if total > 0 else float(valid.mean())
    # intervals between two valid samples close enough to give a velocity
    pair = valid[:-1] & valid[1:] & (dt > 0) & (dt <= MAX_GAP_S)
    speed = np.zeros(max(n - 1, 0))
    speed[pair] = _angles_deg(d[:-1][pair], d[1:][pair]) / dt[pair]
    moving = pair & (speed > threshold_deg_s)
    # saccades: runs of moving intervals; interval k joins samples k and k+1
    edges = np.diff(np.concatenate([[0], moving.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)     # samples start … end
    amplitudes = _angles_deg(d[starts], d[ends]) if len(starts) else np.zeros(0)
    # fixations: the stretches of valid, still samples between saccades, gaps and invalid samples
    still = pair & ~moving
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    f_starts, f_ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    durations = t[f_ends] - t[f_starts] if len(f_starts) else np.zeros(0)
    fixations = durations[durations >= MIN_FIXATION_S - 1e-9]
    return GazeMetrics(samples=n, valid_share=round(valid_share, 4), fixations=int(len(fixations)),
                       mean_fixation_s=round(float(fixations.mean()), 4) if len(fixations) else math.nan,
                       saccades=int(len(starts)),
                       mean_saccade_amplitude_deg=round(float(amplitudes.mean()), 3) if len(amplitudes) else math.nan)


def trial_gaze_metrics(run_dir: str | Path, start_t: float, end_t: float) -> GazeMetrics | None:
    """Gaze metrics of the samples a trial's run log holds between sim times ``start_t`` and
    ``end_t`` [s]; None when it logged no gaze."""
    from raspv_sim.experiment_log import read_gaze, sim_time_at_start

    cols = {k: np.asarray(v, float) for k, v in read_gaze(run_dir).items()}
    if not len(cols["t"]):
        return None
    t = cols["t"] + sim_time_at_start(run_dir)
    keep = (t >= start_t - 1e-6) & (t <= end_t + 1e-6)
    if not keep.any():
        return None
    order = np.argsort(cols["stamp"][keep], kind="stable")
    stamps = cols["stamp"][keep][order]
    directions = np.column_stack([cols["x"], cols["y"], cols["z"]])[keep][order]
    return gaze_metrics(stamps, directions, cols["valid"][keep][order] > 0.5)
