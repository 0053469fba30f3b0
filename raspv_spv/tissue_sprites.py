"""Round phosphenes from tissue geometry, per electrode, for precomputed sprites (no ROS).

- **Scoreboard** (Beyeler et al. 2019; pulse2percept 0.11 ``ScoreboardModel``, retina and
  cortex): the current spreads as a Gaussian exp(−d²/2ρ²) of the distance d on the tissue (µm)
  between the electrode and the point of the visual field's retinal or cortical position.
  On the retina (Watson 2014) the phosphene is a near-round blob; on the cortex
  (:class:`~raspv_spv.retinotopy.WedgeDipoleMap`) it is the blob seen through the cortical
  magnification — small near fixation, large and stretched in the periphery — and an
  electrode only lights its own hemisphere's half of the visual field, the vertical meridian
  blended with a Gaussian of 0.1 dva as pulse2percept does.
- **dynaphos** (van der Grinten et al. 2024, eLife; dynaphos 0.1.3 ``GaussianSimulator``): a
  Gaussian in the visual field around the electrode's phosphene position, of standard
  deviation σ = r2s·√(I / I_spread) / M(e) dva for a current I (A), with the current spread
  I_spread = 675 µA (Tehovnik 2007's size law), r2s = 0.5 and M(e) the cortical magnification
  (mm/dva) at its eccentricity e.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from raspv_spv.retinotopy import WedgeDipoleMap, watson_dva_to_ret

DYNAPHOS_CURRENT_SPREAD_A = 675e-6
DYNAPHOS_RADIUS_TO_SIGMA = 0.5


def _gaussian_columns(points: np.ndarray, centres: np.ndarray, sigma: np.ndarray, gain: np.ndarray,
                      min_weight: float, allowed=None) -> sp.csc_matrix:
    """Sparse (points, E): gain[e]·exp(−|p − c_e|²/2σ_e²) where ≥ min_weight·gain[e]; points
    with NaN coordinates are never lit; ``allowed(e, idx)`` may restrict the points of e."""
    n_pts, n_el = len(points), len(centres)
    ok = np.all(np.isfinite(points), axis=1)
    idx_ok = np.flatnonzero(ok)
    tree = cKDTree(points[ok]) if idx_ok.size else None
    cutoff = math.sqrt(-2.0 * math.log(min_weight))
    rows, cols, vals = [], [], []
    for e in range(n_el):
        if tree is None or not np.all(np.isfinite(centres[e])):
            continue
        near = idx_ok[np.asarray(tree.query_ball_point(centres[e], r=cutoff * sigma[e]), dtype=np.int64)]
        if allowed is not None and near.size:
            near = near[allowed(e, near)]
        if not near.size:
            continue
        d2 = np.sum((points[near] - centres[e]) ** 2, axis=1)
        w = np.exp(-d2 / (2.0 * sigma[e] ** 2))
        keep = w >= min_weight
        rows.append(near[keep])
        cols.append(np.full(int(keep.sum()), e))
        vals.append(gain[e] * w[keep])
    if rows:
        r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    else:
        r = c = np.zeros(0, np.int64)
        v = np.zeros(0)
    return sp.csc_matrix((v.astype(np.float32), (r, c)), shape=(n_pts, n_el))


def retinal_scoreboard_sprites(x_deg, y_deg, electrodes_um: np.ndarray, rho_um: float,
                               min_weight: float = 1e-3) -> sp.csc_matrix:
    """Sparse (points, E): exp(−d²/2ρ²), d the retinal distance (µm) from electrode e to the
    retinal position of each visual-field point (x_deg, y_deg)."""
    xr, yr = watson_dva_to_ret(np.ravel(x_deg), np.ravel(y_deg))
    el = np.asarray(electrodes_um, dtype=np.float64).reshape(-1, 2)
    n = len(el)
    return _gaussian_columns(np.stack([xr, yr], axis=1), el, np.full(n, float(rho_um)), np.ones(n), min_weight)


def cortical_scoreboard_sprites(x_deg, y_deg, electrodes_um: np.ndarray, rho_um: float, cortical_map: WedgeDipoleMap,
                                min_weight: float = 1e-3) -> sp.csc_matrix:
    """Sparse (points, E): exp(−d²/2ρ²), d the V1 distance (µm) from electrode e to the V1
    position of each visual-field point, for points in the electrode's hemisphere only."""
    xv, yv = cortical_map.dva_to_v1(np.ravel(x_deg), np.ravel(y_deg))
    pts = np.stack([xv, yv], axis=1)
    el = np.asarray(electrodes_um, dtype=np.float64).reshape(-1, 2)
    n = len(el)
    point_left = cortical_map.hemisphere(np.nan_to_num(xv, nan=0.0))
    el_left = cortical_map.hemisphere(el[:, 0])
    return _gaussian_columns(pts, el, np.full(n, float(rho_um)), np.ones(n), min_weight,
                             allowed=lambda e, idx: point_left[idx] == el_left[e])


def dynaphos_sigma_deg(centres_deg: np.ndarray, current_a, cortical_map: WedgeDipoleMap) -> np.ndarray:
    """dynaphos' phosphene size: σ (dva) = r2s·√(I/I_spread)/M(eccentricity) for currents I (A)."""
    ecc = np.hypot(centres_deg[:, 0], centres_deg[:, 1])
    return (DYNAPHOS_RADIUS_TO_SIGMA * np.sqrt(np.asarray(current_a, dtype=np.float64) / DYNAPHOS_CURRENT_SPREAD_A)
            / cortical_map.magnification(ecc))


def dynaphos_sprites(x_deg, y_deg, centres_deg: np.ndarray, currents_a: np.ndarray, gains: np.ndarray,
                     cortical_map: WedgeDipoleMap, min_weight: float = 1e-3) -> sp.csc_matrix:
    """Sparse (points, E·L), column e·L + l: gains[l]·exp(−|p − c_e|²/2σ²) with σ dynaphos'
    size for current ``currents_a[l]`` at phosphene e's eccentricity (``centres_deg`` (E, 2))."""
    centres = np.asarray(centres_deg, dtype=np.float64).reshape(-1, 2)
    currents = np.asarray(currents_a, dtype=np.float64).ravel()
    gains = np.asarray(gains, dtype=np.float64).ravel()
    n_el, n_lv = len(centres), len(currents)
    rep = np.repeat(centres, n_lv, axis=0)
    sigma = dynaphos_sigma_deg(rep, np.tile(currents, n_el), cortical_map)
    pts = np.stack([np.ravel(x_deg), np.ravel(y_deg)], axis=1).astype(np.float64)
    return _gaussian_columns(pts, rep, np.where(np.isfinite(sigma), sigma, 1e-9), np.tile(gains, n_el), min_weight)
