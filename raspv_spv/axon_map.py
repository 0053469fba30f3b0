"""The axon-map model of Beyeler et al. 2019 (Sci. Rep. 9:9199) as pulse2percept 0.11's
``AxonMapModel`` computes it, per electrode, for precomputed sprites (no ROS).

An epiretinal electrode stimulates the axons passing under it, so the phosphene is the set of
ganglion cells whose axon passes near the electrode on its way to the optic disc: a streak.
For a point p of the visual field (its ganglion cell at p's retinal position), the axon is the
nearest nerve-fibre bundle's segments from p's nearest segment back towards the optic disc;
a segment at path length d from the soma has sensitivity exp(−d²/2λ²) (dropped below
``min_ax_sensitivity``). Electrode e at retinal position x_e gives p the brightness

    max over p's segments s of  sens(s) · exp(−|x_s − x_e|² / 2ρ²)

(pulse2percept takes the max over segments of the sum over electrodes; for one electrode
the two agree, and the renderer sums sprites, so several electrodes add where pulse2percept
would take the larger). Bundles follow Jansonius et al. 2009 (Vision Res. 49:2157) with the
optic disc at ``loc_od_deg`` (mirrored for a left eye); µm on the retina, dva in the visual
field (:mod:`raspv_spv.retinotopy`, Watson 2014). The horizontal meridian, where bundles from
above and below meet, is blended with a Gaussian of ``meridian_blend_deg`` as pulse2percept does.

The biphasic axon map (Granley & Beyeler 2021) reuses this with ρ, λ and the brightness
scaled per electrode (:mod:`raspv_spv.biphasic_axon_map`): ``sens ** (1/F_streak)`` is the
sensitivity with λ² scaled by F_streak, the segments kept being those of the base λ.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import cKDTree

from raspv_spv.retinotopy import watson_dva_to_ret

EYES = ("right", "left")


@dataclass(frozen=True)
class AxonMapParams:
    """Axon-map geometry and spread (pulse2percept 0.11 ``AxonMapModel`` defaults).

    ``rho_um``: spread away from the axon; ``axlambda_um``: decay along it (µm on the retina).
    ``loc_od_deg``: optic disc (dva; its x sign follows the eye). Bundles: ``n_axons`` initial
    angles over ``axons_range_deg``, ``n_ax_segments`` samples of the Jansonius radial
    coordinate over ``ax_segments_range``.
    """

    rho_um: float = 300.0
    axlambda_um: float = 500.0
    eye: str = "right"
    loc_od_deg: tuple[float, float] = (15.5, 1.5)
    n_axons: int = 1000
    axons_range_deg: tuple[float, float] = (-180.0, 180.0)
    n_ax_segments: int = 500
    ax_segments_range: tuple[float, float] = (0.0, 50.0)
    min_ax_sensitivity: float = 1e-3
    meridian_blend_deg: float = 1.0

    def __post_init__(self) -> None:
        problems = []
        if not (math.isfinite(self.rho_um) and self.rho_um > 0):
            problems.append(f"rho must be > 0 µm, got {self.rho_um}")
        if not (math.isfinite(self.axlambda_um) and self.axlambda_um >= 10):
            problems.append(f"axlambda must be >= 10 µm (below, use the scoreboard model), got {self.axlambda_um}")
        if self.eye not in EYES:
            problems.append(f"eye must be one of {', '.join(EYES)}, got {self.eye!r}")
        if not 0 < self.min_ax_sensitivity < 1:
            problems.append(f"min_ax_sensitivity must be in (0, 1), got {self.min_ax_sensitivity}")
        if self.n_axons < 1 or self.n_ax_segments < 2:
            problems.append("n_axons must be >= 1 and n_ax_segments >= 2")
        if problems:
            raise ValueError("axon map: " + "; ".join(problems))


def jansonius_bundle(phi0: float, rho: np.ndarray, loc_od_deg: tuple[float, float], eye: str = "right",
                     beta_sup: float = -1.9, beta_inf: float = 0.5) -> np.ndarray:
    """One nerve-fibre bundle (N, 2) dva, ordered away from the optic disc (Jansonius 2009
    eqs. 2–6, shifted to the fovea with their appendix A correction, as pulse2percept)."""
    od_x, od_y = loc_od_deg
    if eye == "left":
        od_x = -od_x
    if phi0 > 0:
        b = math.exp(beta_sup + 3.9 * math.tanh(-(phi0 - 121.0) / 14.0))
        c = 1.9 + 1.4 * math.tanh((phi0 - 121.0) / 14.0)
    else:
        b = -math.exp(beta_inf + 1.5 * math.tanh(-(-phi0 - 90.0) / 25.0))
        c = 1.0 + 0.5 * math.tanh((-phi0 - 90.0) / 25.0)
    phi = phi0 + b * (rho - rho[0]) ** c
    xp = rho * np.cos(np.radians(phi))
    yp = rho * np.sin(np.radians(phi))
    cross = np.flatnonzero(yp < 0) if phi0 > 0 else np.flatnonzero(yp > 0)   # first meridian crossing
    if cross.size:
        xp, yp = xp[:cross[0]], yp[:cross[0]]
    x = xp + od_x
    y = yp.copy()
    near = xp > -od_x if od_x > 0 else xp < -od_x
    y[near] = yp[near] + od_y * (x[near] / od_x) ** 2
    if eye == "left":
        x = -x
    return np.stack([x, y], axis=1)


class AxonBundles:
    """The nerve-fibre bundles crossing a visual-field window, on the retina (µm), with the
    path length along each bundle, ready to find every point's axon."""

    def __init__(self, params: AxonMapParams, xrange_deg: tuple[float, float], yrange_deg: tuple[float, float]) -> None:
        self.params = params
        rho = np.linspace(*params.ax_segments_range, num=params.n_ax_segments)
        bundles = []
        for phi0 in np.linspace(*params.axons_range_deg, num=params.n_axons):
            b = jansonius_bundle(float(phi0), rho, params.loc_od_deg, params.eye)
            if len(b) <= 10:
                continue
            # the bundles pulse2percept keeps: those whose box overlaps the simulated window
            if (b[:, 0].max() >= xrange_deg[0] and b[:, 0].min() <= xrange_deg[1]
                    and b[:, 1].max() >= yrange_deg[0] and b[:, 1].min() <= yrange_deg[1]):
                bundles.append(np.stack(watson_dva_to_ret(b[:, 0], b[:, 1]), axis=1))
        if not bundles:
            raise ValueError(f"no nerve fibre bundle crosses the window x {xrange_deg}, y {yrange_deg} deg")
        lengths = np.array([len(b) for b in bundles])
        self.offsets = np.concatenate(([0], np.cumsum(lengths)))
        self.segments = np.concatenate(bundles)                    # (S, 2) µm
        step = np.hypot(*np.diff(self.segments, axis=0).T)
        step[self.offsets[1:-1] - 1] = 0.0                         # do not cross bundle seams
        arc = np.concatenate(([0.0], np.cumsum(step)))
        self.arc = arc - np.repeat(arc[self.offsets[:-1]], lengths)   # path length from each bundle's start
        self.bundle_of = np.repeat(np.arange(len(bundles)), lengths)
        self._tree = cKDTree(self.segments, leafsize=60)

    def axons(self, x_deg: np.ndarray, y_deg: np.ndarray) -> "AxonSegments":
        """Each point's axon: its segments from the soma back towards the optic disc, with
        their sensitivity (sensitivity below ``min_ax_sensitivity`` dropped)."""
        p = self.params
        xr, yr = watson_dva_to_ret(np.ravel(x_deg), np.ravel(y_deg))
        pts = np.stack([xr, yr], axis=1)
        d0, seg = self._tree.query(pts)
        bundle = self.bundle_of[seg]
        start = self.offsets[bundle]
        reach = p.axlambda_um * math.sqrt(-2.0 * math.log(p.min_ax_sensitivity))
        soma_arc = self.arc[seg] + d0                               # path length soma -> bundle start
        # segments k <= seg of the same bundle with soma_arc - arc[k] < reach (a contiguous run)
        span = self.arc.max() + reach + 1.0
        keyed = self.arc + self.bundle_of * span
        lo = np.searchsorted(keyed, soma_arc - reach + bundle * span, side="right")
        n_keep = np.maximum(seg - np.maximum(lo, start) + 1, 0)
        point = np.repeat(np.arange(len(pts)), n_keep)
        first = np.concatenate(([0], np.cumsum(n_keep)))[:-1]
        k = np.repeat(seg, n_keep) - (np.arange(int(n_keep.sum())) - np.repeat(first, n_keep))
        dist = np.repeat(soma_arc, n_keep) - self.arc[k]
        sens = np.exp(-dist ** 2 / (2.0 * p.axlambda_um ** 2))
        return AxonSegments(len(pts), point, k, sens, self.segments)


class AxonSegments:
    """(point, segment) pairs of a set of points: ``point`` (M,) index of the point,
    ``segment`` (M,) index into ``segments_um`` (S, 2) (bundle segments on the retina, µm),
    ``sensitivity`` (M,) exp(−d²/2λ²) for the segment's path length d to the point's soma.
    Pairs are ordered by point."""

    def __init__(self, num_points: int, point: np.ndarray, segment: np.ndarray, sensitivity: np.ndarray,
                 segments_um: np.ndarray) -> None:
        self.num_points = num_points
        self.point = point
        self.segment = segment
        self.sensitivity = sensitivity
        self.segments_um = segments_um
        # the segments some point uses, and for each the pairs that use it (CSR)
        self.used, inverse = np.unique(segment, return_inverse=True)
        self._pairs_by_segment = np.argsort(inverse, kind="stable")
        self._indptr = np.concatenate(([0], np.cumsum(np.bincount(inverse, minlength=len(self.used)))))
        self._tree = cKDTree(segments_um[self.used]) if len(self.used) else None

    @property
    def xy_um(self) -> np.ndarray:
        """(M, 2) the segment of every pair."""
        return self.segments_um[self.segment]

    def pairs_near(self, xy_um: np.ndarray, radius_um: float) -> tuple[np.ndarray, np.ndarray]:
        """(pair indices, squared distance of their segment to ``xy_um``) for the pairs whose
        segment lies within ``radius_um``."""
        if self._tree is None:
            return np.zeros(0, np.int64), np.zeros(0)
        near = np.asarray(self._tree.query_ball_point(xy_um, r=radius_um), dtype=np.int64)
        if not near.size:
            return np.zeros(0, np.int64), np.zeros(0)
        d2_seg = np.sum((self.segments_um[self.used[near]] - xy_um) ** 2, axis=1)
        lengths = self._indptr[near + 1] - self._indptr[near]
        offsets = np.repeat(self._indptr[near] - np.concatenate(([0], np.cumsum(lengths)))[:-1], lengths)
        pairs = self._pairs_by_segment[np.arange(int(lengths.sum())) + offsets]
        return pairs, np.repeat(d2_seg, lengths)


def axon_sprites(axons: AxonSegments, electrodes_um: np.ndarray, rho_um, streak_power=1.0, brightness=1.0,
                 min_weight: float = 1e-3) -> sp.csc_matrix:
    """Sparse (points, E·L) brightness of each electrode's phosphene at every point. ``rho_um``,
    ``streak_power`` and ``brightness`` are scalars, (E,) or (E, L) (L variants of each
    electrode, e.g. pulse amplitudes); column e·L + l is
    ``brightness[e, l] · max_s sens(s)^streak_power[e, l] · exp(−|x_s − x_e|² / 2 rho[e, l]²)``,
    values below ``min_weight`` · brightness[e, l] dropped."""
    electrodes_um = np.asarray(electrodes_um, dtype=np.float64).reshape(-1, 2)
    n_el = len(electrodes_um)
    shaped = [np.asarray(a, dtype=np.float64) for a in (rho_um, streak_power, brightness)]
    n_lv = max(a.shape[1] if a.ndim == 2 else 1 for a in shaped)
    rho, power, gain = (np.broadcast_to(a.reshape(-1, 1) if a.ndim == 1 else a, (n_el, n_lv)) for a in shaped)
    cutoff = math.sqrt(-2.0 * math.log(min_weight))
    rows, cols, vals = [], [], []
    best = np.zeros(axons.num_points)
    for e in range(n_el):
        pairs, d2 = axons.pairs_near(electrodes_um[e], cutoff * float(rho[e].max()))
        if not pairs.size:
            continue
        pts = axons.point[pairs]
        sens = axons.sensitivity[pairs]
        touched = np.unique(pts)
        for lv in range(n_lv):
            w = (sens if power[e, lv] == 1.0 else sens ** power[e, lv]) * np.exp(-d2 / (2.0 * rho[e, lv] ** 2))
            best[touched] = 0.0
            np.maximum.at(best, pts, w)                     # max over each point's segments
            lit = touched[best[touched] >= min_weight]
            rows.append(lit)
            vals.append(gain[e, lv] * best[lit])
            cols.append(np.full(lit.size, e * n_lv + lv))
    if rows:
        r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    else:
        r = c = np.zeros(0, np.int64)
        v = np.zeros(0)
    return sp.csc_matrix((v.astype(np.float32), (r, c)), shape=(axons.num_points, n_el * n_lv))


def blend_meridian(sprites: sp.csc_matrix, grid_shape: tuple[int, int], coordinate: np.ndarray, width_deg: float,
                   axis: int) -> sp.csc_matrix:
    """pulse2percept's ``_blend_meridian`` on every sprite (column) of a grid of
    ``grid_shape`` (rows, cols): a Gaussian of ``width_deg`` across the meridian where
    ``coordinate`` (the grid's y for the horizontal meridian, x for the vertical; same shape)
    is 0, along ``axis`` (0: across rows, 1: across columns), tapered by exp(−c²/2w²)."""
    if not width_deg or width_deg <= 0:
        return sprites
    coordinate = np.asarray(coordinate, dtype=np.float64).reshape(grid_shape)
    along = coordinate[:, 0] if axis == 0 else coordinate[0, :]
    if along.size < 2 or not (np.any(along < 0) and np.any(along > 0)):
        return sprites
    spacing = float(np.abs(np.diff(along)).mean())
    weight = np.exp(-coordinate ** 2 / (2.0 * width_deg ** 2)).astype(np.float32)
    out = sprites.tocsc().astype(np.float32)
    blended = []
    chunk = max(1, 4_000_000 // max(1, grid_shape[0] * grid_shape[1]))
    for start in range(0, out.shape[1], chunk):
        dense = out[:, start:start + chunk].toarray().reshape(grid_shape + (-1,))
        blurred = gaussian_filter1d(dense, width_deg / spacing, axis=axis, mode="nearest")
        dense += weight[..., None] * (blurred - dense)
        blended.append(sp.csc_matrix(dense.reshape(grid_shape[0] * grid_shape[1], -1)))
    return sp.hstack(blended, format="csc")
