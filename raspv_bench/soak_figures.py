"""Long-run figures of a graph (no rclpy): memory growth per node and dropped display frames.

- :class:`RssSeries` collects (time, resident memory) samples of one node (in total, or one
  kind of it: :func:`proc_memory` splits private heap from shared-memory pages); a restart (new pid)
  starts a new segment, since a fresh process's memory says nothing about the old one's growth.
  :meth:`RssSeries.growth` fits a straight line (``scipy.stats.linregress``) to the samples
  after a warm-up, per segment, and reports the slope in MB/hour with its standard error —
  weighted by segment length when a node restarted — and the slope over the second half of
  the samples alone: memory that fills up to a bound (allocator pools, caches) has a positive
  overall slope and a late slope near zero; a leak keeps both.
- :func:`display_gaps` counts the display frames missing between consecutive ``/spv/frame``
  stamps (the spv node stamps each frame at its display tick, so a late or skipped tick shows
  as a gap whatever the transport does).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Growth:
    """Fitted memory growth: ``slope_mb_h`` ± ``stderr_mb_h`` over ``span_s`` seconds of samples
    after the warm-up; ``first_mb``/``last_mb`` of those samples."""

    slope_mb_h: float
    stderr_mb_h: float
    span_s: float
    samples: int
    first_mb: float
    last_mb: float
    late_slope_mb_h: float = 0.0       # over the second half of the samples: ~0 when the growth levels off
    late_stderr_mb_h: float = 0.0


@dataclass
class RssSeries:
    name: str
    segments: list[tuple[int, list[float], list[float]]] = field(default_factory=list)   # (pid, times s, RSS MB)

    def add(self, pid: int, t_s: float, rss_bytes: int) -> None:
        if not self.segments or self.segments[-1][0] != pid:
            self.segments.append((pid, [], []))
        self.segments[-1][1].append(float(t_s))
        self.segments[-1][2].append(rss_bytes / 1e6)

    @property
    def restarts(self) -> int:
        return max(0, len(self.segments) - 1)

    def growth(self, warmup_s: float) -> Growth | None:
        """The fitted growth after ``warmup_s`` seconds of each segment (None: too few samples)."""
        from scipy.stats import linregress

        fits = []
        for _, t, mb in self.segments:
            t_arr, mb_arr = np.asarray(t), np.asarray(mb)
            keep = t_arr >= t_arr[0] + warmup_s if t_arr.size else t_arr.astype(bool)
            t_arr, mb_arr = t_arr[keep], mb_arr[keep]
            if t_arr.size < 3 or t_arr[-1] - t_arr[0] <= 0:
                continue
            fit = linregress(t_arr, mb_arr)
            half = t_arr >= t_arr[0] + 0.5 * (t_arr[-1] - t_arr[0])
            late = linregress(t_arr[half], mb_arr[half]) if half.sum() >= 3 else fit
            fits.append((fit.slope * 3600.0, fit.stderr * 3600.0, t_arr[-1] - t_arr[0], t_arr.size,
                         float(mb_arr[0]), float(mb_arr[-1]), late.slope * 3600.0, late.stderr * 3600.0))
        if not fits:
            return None
        spans = np.array([f[2] for f in fits])
        w = spans / spans.sum()

        def combine(i: int, j: int) -> tuple[float, float]:
            return float(np.sum(w * [f[i] for f in fits])), float(math.sqrt(np.sum((w * [f[j] for f in fits]) ** 2)))

        (slope, stderr), (late, late_err) = combine(0, 1), combine(6, 7)
        return Growth(slope, stderr, float(spans.sum()), int(sum(f[3] for f in fits)), fits[0][4], fits[-1][5],
                      late, late_err)


def proc_memory(pid: int) -> dict[str, int]:
    """Resident memory of a process by kind [bytes], from ``/proc/<pid>/status``: ``anon``
    (private heap: what a leak grows), ``shmem`` (shared-memory pages touched, e.g. the DDS
    segments of this and other processes — bounded by their sizes), ``file`` (mapped files)."""
    out = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            for key, name in (("RssAnon:", "anon"), ("RssShmem:", "shmem"), ("RssFile:", "file")):
                if line.startswith(key):
                    out[name] = int(line.split()[1]) * 1024
    return out


def display_gaps(stamps_s: list[float] | np.ndarray, rate_hz: float) -> int:
    """Display frames missing between consecutive frame stamps [s] at ``rate_hz``: a step of
    k periods (rounded) means k − 1 frames were not shown."""
    s = np.sort(np.asarray(stamps_s, dtype=float))
    if s.size < 2:
        return 0
    steps = np.rint(np.diff(s) * rate_hz)
    return int(np.sum(np.maximum(steps - 1, 0)))
