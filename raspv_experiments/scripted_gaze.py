"""Scripted eye gaze for tests and virtual patients (no rclpy): fixations and saccades from a
simple seeded model, or a recorded gaze trace file.

The model (:func:`model_trace`) alternates fixations and saccades, as eyes do when looking
around a scene:

- fixation durations ~ gamma (shape 4, mean ``mean_fixation_s`` = 0.28 s: scene-viewing
  fixations last 260–330 ms on average, right-skewed; Henderson & Hollingworth 1999, Rayner
  2009), with fixational jitter (``jitter_deg`` = 0.05° std. dev. per sample, below any
  velocity threshold at 120 Hz);
- saccade amplitudes ~ gamma (shape 2, mean ``mean_amplitude_deg`` = 6°: most scene-viewing
  saccades are under 15°, Bahill, Adler & Stark 1975; Tatler et al. 2006) in a uniform direction,
  kept within ``max_eccentricity_deg`` = 15° of straight ahead (larger gaze shifts recruit the
  head, Freedman 2008): a target outside is reflected inside;
- saccade durations from the main sequence, D = 21 ms + 2.2 ms/° · A (Carpenter 1988), with
  the minimum-jerk position profile 10τ³ − 15τ⁴ + 6τ⁵ (peak velocity 1.875 A/D: 400°/s for 12°);
- blinks at ``blink_rate_hz`` = 0.25 (15 a minute, Doughty 2001) of 150 ms, samples invalid.

The same seed and duration give the same trace. A trace file is CSV with a header, either
``t,x,y,z,valid`` (unit direction in the head frame: x forward, y left, z up) or
``t,yaw_deg,pitch_deg,valid`` (yaw > 0 left, pitch > 0 down); ``t`` in seconds from the start.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from raspv_spv.gaze import direction_from_angles


@dataclass(frozen=True)
class GazeModelConfig:
    rate_hz: float = 120.0
    mean_fixation_s: float = 0.28
    mean_amplitude_deg: float = 6.0
    max_eccentricity_deg: float = 15.0
    jitter_deg: float = 0.05
    blink_rate_hz: float = 0.25
    blink_s: float = 0.15


@dataclass(frozen=True)
class GazeTrace:
    """Samples: ``t`` (N,) [s from the start], ``directions`` (N, 3) unit in the head frame,
    ``valid`` (N,) bool."""

    t: np.ndarray
    directions: np.ndarray
    valid: np.ndarray

    def __len__(self) -> int:
        return len(self.t)

    def between(self, t0: float, t1: float) -> "GazeTrace":
        """The samples with t0 < t ≤ t1 [s]."""
        k = (self.t > t0) & (self.t <= t1)
        return GazeTrace(self.t[k], self.directions[k], self.valid[k])

    def save(self, path: str | Path) -> None:
        """Write the trace as ``t,x,y,z,valid`` CSV."""
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["t", "x", "y", "z", "valid"])
            for t, d, v in zip(self.t, self.directions, self.valid):
                w.writerow([f"{t:.6f}", *(f"{c:.6f}" for c in d), int(v)])


def main_sequence_s(amplitude_deg: float) -> float:
    """Saccade duration [s] of an amplitude [deg] (Carpenter 1988)."""
    return 0.021 + 0.0022 * amplitude_deg


def model_trace(duration_s: float, seed: int, config: GazeModelConfig = GazeModelConfig()) -> GazeTrace:
    """A gaze trace of ``duration_s`` [s] from the model (see the module docstring)."""
    rng = np.random.default_rng(seed)
    c = config
    n = int(math.floor(duration_s * c.rate_hz)) + 1
    t = np.arange(n) / c.rate_hz
    angles = np.zeros((n, 2))                # yaw, pitch [deg]
    here = np.zeros(2)
    i = 0
    while i < n:
        fix = rng.gamma(4.0, c.mean_fixation_s / 4.0)
        j = min(n, i + max(1, int(round(fix * c.rate_hz))))
        angles[i:j] = here + rng.normal(0.0, c.jitter_deg, (j - i, 2))
        i = j
        if i >= n:
            break
        amplitude = rng.gamma(2.0, c.mean_amplitude_deg / 2.0)
        heading = rng.uniform(0.0, 2 * math.pi)
        target = here + amplitude * np.array([math.cos(heading), math.sin(heading)])
        r = float(np.hypot(*target))
        if r > c.max_eccentricity_deg:           # reflected back inside the eccentricity limit
            target *= max(0.0, 2 * c.max_eccentricity_deg - r) / r
        amp = float(np.hypot(*(target - here)))
        k = max(1, int(round(main_sequence_s(amp) * c.rate_hz)))
        tau = np.arange(1, k + 1) / k
        profile = 10 * tau ** 3 - 15 * tau ** 4 + 6 * tau ** 5
        j = min(n, i + k)
        angles[i:j] = here + np.outer(profile[:j - i], target - here)
        here = target
        i = j
    valid = np.ones(n, bool)
    blink_t = 0.0
    while True:
        blink_t += rng.exponential(1.0 / c.blink_rate_hz) if c.blink_rate_hz > 0 else math.inf
        if blink_t >= duration_s:
            break
        valid[(t >= blink_t) & (t < blink_t + c.blink_s)] = False
    return GazeTrace(t, directions_from_angles(angles[:, 0], angles[:, 1]), valid)


def directions_from_angles(yaw_deg: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """(N, 3) unit head-frame directions of Fick angles [deg] (:func:`raspv_spv.gaze.direction_from_angles`)."""
    y, p = np.radians(yaw_deg), np.radians(pitch_deg)
    return np.column_stack([np.cos(p) * np.cos(y), np.cos(p) * np.sin(y), -np.sin(p)])


class GazeScript:
    """A trace played from sim time ``origin`` [s]: :meth:`due` hands out the samples whose time
    came, once each, stamped origin + t; a trace that ends starts over."""

    def __init__(self, trace: GazeTrace, origin: float) -> None:
        if len(trace) == 0:
            raise ValueError("an empty gaze trace")
        self.trace, self.origin = trace, float(origin)
        self.period = float(trace.t[-1] - trace.t[0]) + (float(np.median(np.diff(trace.t))) if len(trace) > 1 else 1.0)
        self._next = 0                              # index of the next sample over all repetitions

    def due(self, now: float) -> list[tuple[float, np.ndarray | None]]:
        """(stamp [s], unit direction or None when invalid) of the samples up to sim time ``now``."""
        out = []
        n = len(self.trace)
        while True:
            k, rep = self._next % n, self._next // n
            stamp = self.origin + rep * self.period + float(self.trace.t[k] - self.trace.t[0])
            if stamp > now + 1e-9 or len(out) > 10_000:
                return out
            out.append((stamp, self.trace.directions[k] if self.trace.valid[k] else None))
            self._next += 1


def load_trace(path: str | Path) -> GazeTrace:
    """A recorded trace file (see the module docstring); ValueError naming the file and line."""
    from raspv_common.text_files import read_text_file

    text = read_text_file(path, "gaze trace")
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise ValueError(f"{path}: empty gaze trace; expected a header t,x,y,z,valid or t,yaw_deg,pitch_deg,valid")
    header = [h.strip() for h in rows[0]]
    if header == ["t", "x", "y", "z", "valid"]:
        angles = False
    elif header == ["t", "yaw_deg", "pitch_deg", "valid"]:
        angles = True
    else:
        raise ValueError(f"{path}: line 1: header {','.join(header)!r}; expected t,x,y,z,valid or "
                         "t,yaw_deg,pitch_deg,valid")
    t, dirs, valid = [], [], []
    for number, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        try:
            values = [float(v) for v in row]
        except ValueError:
            raise ValueError(f"{path}: line {number}: {','.join(row)!r} is not {len(header)} numbers") from None
        if len(values) != len(header) or not all(math.isfinite(v) for v in values):
            raise ValueError(f"{path}: line {number}: expected {len(header)} finite numbers, got {','.join(row)!r}")
        ok = values[-1] > 0.5
        if angles:
            d = direction_from_angles(values[1], values[2])
        else:
            v = np.array(values[1:4])
            norm = float(np.linalg.norm(v))
            if ok and norm < 1e-9:
                raise ValueError(f"{path}: line {number}: a valid sample with a zero direction")
            d = v / norm if norm >= 1e-9 else np.array([1.0, 0.0, 0.0])
        if t and values[0] <= t[-1]:
            raise ValueError(f"{path}: line {number}: time {values[0]} does not increase")
        t.append(values[0])
        dirs.append(d)
        valid.append(ok)
    if not t:
        raise ValueError(f"{path}: no samples")
    return GazeTrace(np.array(t), np.array(dirs), np.array(valid))


def displayed_layout_index(centres: np.ndarray, offset_px: tuple[float, float], spacing_px: float):
    """For each phosphene i of ``centres`` (N, 2) [px], the phosphene j drawn nearest to where i
    sits when the field is shifted by ``offset_px`` (centres_j + offset ≈ centres_i), or −1 when
    none is within half a spacing: what a subject who knows where its phosphenes are sees at each
    of them when the field moves with the eye (``index`` → brightness[index], −1 dark)."""
    from scipy.spatial import cKDTree

    centres = np.asarray(centres, float)
    tree = cKDTree(centres + np.asarray(offset_px, float))
    dist, idx = tree.query(centres, distance_upper_bound=0.5 * spacing_px)
    return np.where(np.isfinite(dist), idx, -1)
