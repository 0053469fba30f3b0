"""Plane fitting, 1-D histogram peaks and plane hulls (no ROS). Camera frame C, metres."""
from __future__ import annotations

import math

import cv2
import numpy as np


def fit_plane(points: np.ndarray, max_points: int = 4000) -> np.ndarray:
    """Least-squares plane (a, b, c, d) through points (N ≥ 3, 3): (a, b, c) unit, oriented
    towards the origin (the camera), so d ≥ 0 is the camera's distance to the plane.
    Uses an evenly spaced subset of at most ``max_points`` points."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) < 3:
        raise ValueError(f"a plane needs at least 3 points, got {len(p)}")
    if len(p) > max_points:
        p = p[:: int(math.ceil(len(p) / max_points))]
    c = p.mean(axis=0)
    q = p - c
    _, vecs = np.linalg.eigh(q.T @ q)
    n = vecs[:, 0]
    d = -float(n @ c)
    if d < 0:
        n, d = -n, -d
    return np.array([n[0], n[1], n[2], d])


def histogram_peaks(values: np.ndarray, weights: np.ndarray, lo: float, hi: float, bin_width: float,
                    min_weight: float, separation: float, circular: bool = False) -> list[tuple[float, float]]:
    """Modes of the ``weights``-weighted histogram of ``values`` in [lo, hi).

    The histogram is smoothed with a [1, 2, 1]/4 kernel; a peak is a bin not smaller than its
    neighbours whose mass within ±``separation``/2 is ≥ ``min_weight``; peaks closer than
    ``separation`` to a stronger one are dropped. Returns (value, mass) pairs, strongest first;
    values are refined by the weighted mean of the bins within ±``separation``/2.
    ``circular`` wraps the histogram (for angles).
    """
    nb = int(math.ceil((hi - lo) / bin_width))
    v = np.asarray(values, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    idx = np.floor((v - lo) / bin_width).astype(np.int64)
    if circular:
        idx %= nb
    else:
        keep = (idx >= 0) & (idx < nb)
        idx, w = idx[keep], w[keep]
    hist = np.bincount(idx, weights=w, minlength=nb)[:nb]
    if circular:
        padded = np.concatenate([hist[-1:], hist, hist[:1]])
    else:
        padded = np.concatenate([[0.0], hist, [0.0]])
    smooth = 0.25 * padded[:-2] + 0.5 * padded[1:-1] + 0.25 * padded[2:]
    half = max(1, int(round(0.5 * separation / bin_width)))
    centres = lo + (np.arange(nb) + 0.5) * bin_width
    if circular:
        wrapped = np.concatenate([hist[nb - half:], hist, hist[:half]]) if half < nb else np.tile(hist, 3)[nb - half:2 * nb + half]
        cs = np.concatenate([[0.0], np.cumsum(wrapped)])
        mass = cs[np.arange(nb) + 2 * half + 1] - cs[np.arange(nb)]
    else:
        cs = np.concatenate([[0.0], np.cumsum(hist)])
        a = np.clip(np.arange(nb) - half, 0, nb)
        b = np.clip(np.arange(nb) + half + 1, 0, nb)
        mass = cs[b] - cs[a]
    left = np.roll(smooth, 1) if circular else np.concatenate([[-1.0], smooth[:-1]])
    right = np.roll(smooth, -1) if circular else np.concatenate([smooth[1:], [-1.0]])
    cand = np.flatnonzero((smooth >= left) & (smooth >= right) & (mass >= min_weight) & (smooth > 0))
    cand = cand[np.argsort(-mass[cand], kind="stable")]
    peaks: list[tuple[float, float]] = []
    taken: list[int] = []
    for i in cand:
        if any(_bin_distance(i, j, nb, circular) * bin_width < separation for j in taken):
            continue
        taken.append(int(i))
        window = np.arange(i - half, i + half + 1)
        if circular:
            ws = hist[window % nb]
            x = centres[i] + (window - i) * bin_width
        else:
            window = window[(window >= 0) & (window < nb)]
            ws, x = hist[window], centres[window]
        value = float((ws * x).sum() / ws.sum()) if ws.sum() > 0 else float(centres[i])
        if circular:
            value = lo + (value - lo) % (hi - lo)
        peaks.append((value, float(mass[i])))
    return peaks


def _bin_distance(i: int, j: int, nb: int, circular: bool) -> int:
    d = abs(i - j)
    return min(d, nb - d) if circular else d


def cross3(a, b) -> np.ndarray:
    """``np.cross`` of two 3-vectors, with the same operations (so the same bits) minus its
    general-shape overhead (≈15 µs a call)."""
    a0, a1, a2 = a[0], a[1], a[2]
    b0, b1, b2 = b[0], b[1], b[2]
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def plane_basis(normal: np.ndarray, forward: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (e1, e2) spanning the plane ⊥ ``normal``; e2 is ``forward`` (default the
    camera z axis, or y if z is nearly normal) projected on the plane, e1 = e2 × normal."""
    n = np.asarray(normal, dtype=np.float64)
    f = np.array([0.0, 0.0, 1.0]) if forward is None else np.asarray(forward, dtype=np.float64)
    e2 = f - (f @ n) * n
    if np.linalg.norm(e2) < 1e-3:
        f = np.array([0.0, 1.0, 0.0])
        e2 = f - (f @ n) * n
    e2 /= np.linalg.norm(e2)
    e1 = cross3(e2, n)
    return e1, e2


def hull_on_plane(points: np.ndarray, plane: np.ndarray) -> tuple[np.ndarray, float]:
    """Convex hull (K, 3), ordered, of ``points`` projected on ``plane``, and its area [m²]."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n, d = plane[:3], plane[3]
    if len(p) < 3:
        return np.zeros((0, 3)), 0.0
    e1, e2 = plane_basis(n)
    uv = np.stack([p @ e1, p @ e2], axis=1).astype(np.float32)
    hull = cv2.convexHull(uv).reshape(-1, 2).astype(np.float64)
    if len(hull) < 3:
        return np.zeros((0, 3)), 0.0
    area = float(abs(cv2.contourArea(hull.astype(np.float32))))
    origin = -d * n
    pts3 = origin + hull[:, :1] * e1 + hull[:, 1:2] * e2
    return pts3, area
