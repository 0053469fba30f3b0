"""Plane segmentation of an organised cloud with normals, guided by the up direction (no ROS).

Instead of growing regions and running RANSAC one plane at a time (the authors' PCL pipeline,
hundreds of ms), planes are found as modes: upward-facing samples pile up at the heights of the
floor, tables and steps; vertical samples pile up first at the azimuths of the walls, then at
their offsets. Each mode is refitted by least squares, its inliers taken by distance (tolerance
growing with z², like sensor noise) and normal agreement, and split into image-connected
pieces. Slanted planes come from a short RANSAC on what is left. Camera frame C, metres.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from raspv_perception.manhattan import HorizontalBasis
from raspv_perception.plane_fitting import cross3, fit_plane, histogram_peaks
from raspv_perception.scene_config import SceneConfig

LAYER_BIN = 0.02        # height / offset histogram bin [m]
LAYER_SEPARATION = 0.08  # parallel planes closer than this are one mode [m]
AZIMUTH_BIN = 2.0       # azimuth histogram bin [deg]
AZIMUTH_SEPARATION = 12.0  # wall directions closer than this are one mode [deg]


@dataclass
class CloudSamples:
    """Flat views of an organised cloud for plane work: ``points`` (n, 3), ``normals`` (n, 3)
    (NaN where invalid), ``valid``/``has_normal`` (n,) bool, ``area`` (n,) surface area [m²] per
    sample (footprint over |cos incidence|), ``tolerance`` (n,) plane inlier distance [m],
    ``shape`` (h, w) of the organised grid."""

    points: np.ndarray
    normals: np.ndarray
    valid: np.ndarray
    has_normal: np.ndarray
    area: np.ndarray
    tolerance: np.ndarray
    shape: tuple[int, int]

    @classmethod
    def build(cls, points: np.ndarray, valid: np.ndarray, normals: np.ndarray, has_normal: np.ndarray,
              footprint: np.ndarray, config: SceneConfig) -> "CloudSamples":
        h, w = valid.shape
        P = points.reshape(-1, 3)
        N = normals.reshape(-1, 3)
        v = valid.reshape(-1)
        hn = has_normal.reshape(-1)
        z = P[:, 2]
        with np.errstate(invalid="ignore", divide="ignore"):
            rng = np.sqrt(np.einsum("ij,ij->i", P, P))
            cos_inc = np.abs(np.einsum("ij,ij->i", N, P)) / rng
        cos_inc = np.where(hn, np.clip(np.nan_to_num(cos_inc, nan=1.0), 0.15, 1.0), 1.0)
        area = np.where(v, footprint.reshape(-1) / cos_inc, 0.0).astype(np.float32)
        tol = np.where(v, config.inlier_distance(np.nan_to_num(z)), 0.0).astype(np.float32)
        return cls(P, N, v, hn, area, tol, (h, w))


@dataclass
class PlaneSegment:
    """A plane found in the cloud: ``plane`` (a, b, c, d) in C (normal towards the camera),
    ``indices`` the flat indices of its samples (one image-connected piece), ``area`` [m²]."""

    plane: np.ndarray
    indices: np.ndarray
    area: float
    family: str   # "up" (upward-facing layer), "vertical" or "slanted"


def dominant_up(samples: CloudSamples, up0: np.ndarray, max_angle_deg: float, min_area: float,
                bin_size: float = 0.02) -> np.ndarray | None:
    """The most common normal direction within ``max_angle_deg`` of ``up0`` (area-weighted mode
    of the normals on a tangent-plane grid, refined by the mean within 6°), or None when less
    than ``min_area`` [m²] of surface faces that way."""
    up0 = np.asarray(up0, dtype=np.float64) / np.linalg.norm(up0)
    N = samples.normals
    with np.errstate(invalid="ignore"):
        cos = N @ up0.astype(np.float32)
        cand = samples.has_normal & (cos >= math.cos(math.radians(max_angle_deg)))
    if samples.area[cand].sum() < min_area:
        return None
    e1 = cross3(up0, [1.0, 0.0, 0.0] if abs(up0[0]) < 0.9 else [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = cross3(up0, e1)
    n = N[cand].astype(np.float64)
    w = samples.area[cand]
    r = math.sin(math.radians(max_angle_deg))
    nb = int(math.ceil(2 * r / bin_size)) + 1
    a = np.clip(((n @ e1 + r) / bin_size).astype(np.int64), 0, nb - 1)
    b = np.clip(((n @ e2 + r) / bin_size).astype(np.int64), 0, nb - 1)
    hist = np.bincount(a * nb + b, weights=w, minlength=nb * nb).reshape(nb, nb).astype(np.float32)
    hist = cv2.GaussianBlur(hist, (0, 0), 1.5)
    ia, ib = np.unravel_index(int(np.argmax(hist)), hist.shape)
    pa, pb = (ia + 0.5) * bin_size - r, (ib + 0.5) * bin_size - r
    peak = up0 * math.sqrt(max(0.0, 1 - pa * pa - pb * pb)) + pa * e1 + pb * e2
    for _ in range(2):
        near = (n @ peak) >= math.cos(math.radians(6.0))
        if w[near].sum() <= 0:
            break
        m = (n[near] * w[near, None]).sum(axis=0)
        peak = m / np.linalg.norm(m)
    if w[(n @ peak) >= math.cos(math.radians(10.0))].sum() < min_area:
        return None
    return peak


def _inliers(samples: CloudSamples, plane: np.ndarray, pool: np.ndarray, config: SceneConfig,
             allow_no_normal: bool = False) -> np.ndarray:
    """(len(pool),) bool: which samples of ``pool`` (sample indices) lie within tolerance of
    ``plane`` with an agreeing normal (or, with ``allow_no_normal``, have no normal and lie
    within half the tolerance)."""
    P = samples.points[pool]
    n = plane[:3].astype(np.float32)
    with np.errstate(invalid="ignore"):
        dist = np.abs(P @ n + np.float32(plane[3]))
        tol = samples.tolerance[pool]
        agree = (samples.normals[pool] @ n) >= math.cos(math.radians(config.plane_normal_angle_deg))
        ok = (dist < tol) & agree
        if allow_no_normal:
            ok |= ~samples.has_normal[pool] & (dist < 0.5 * tol)
    return ok


def _pieces(samples: CloudSamples, plane: np.ndarray, inliers: np.ndarray, family: str,
            min_area: float) -> tuple[list[PlaneSegment], np.ndarray]:
    """Split inliers (sample indices) into 8-connected image pieces of at least ``min_area``
    (the work is done on the inliers' bounding box). Also returns which inliers were kept."""
    kept = np.zeros(len(inliers), dtype=bool)
    if len(inliers) == 0 or samples.area[inliers].sum() < min_area:
        return [], kept
    h, w = samples.shape
    r, c = np.divmod(inliers, w)
    r0, r1, c0, c1 = r.min(), r.max() + 1, c.min(), c.max() + 1
    crop = np.zeros((r1 - r0, c1 - c0), dtype=np.uint8)
    crop[r - r0, c - c0] = 1
    count, comp = cv2.connectedComponents(crop, connectivity=8)
    ids = comp[r - r0, c - c0]
    areas = np.bincount(ids, weights=samples.area[inliers], minlength=count)
    out = []
    for i in np.flatnonzero(areas >= min_area):
        if i == 0:
            continue
        sel = ids == i
        kept |= sel
        out.append(PlaneSegment(plane, inliers[sel], float(areas[i]), family))
    return out, kept


def _refit(samples: CloudSamples, members: np.ndarray) -> np.ndarray | None:
    if len(members) < 10:
        return None
    return fit_plane(samples.points[members])


def upward_layers(samples: CloudSamples, up: np.ndarray, config: SceneConfig) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Upward-facing planes ⟂ ``up`` (floor, tables, seats, steps) as (plane, inlier sample
    indices, area [m²]) before splitting into pieces, largest first. Inliers are disjoint."""
    up = np.asarray(up, dtype=np.float32)
    cos_n = math.cos(math.radians(config.plane_normal_angle_deg))
    valid = np.flatnonzero(samples.valid)
    with np.errstate(invalid="ignore"):
        nu = samples.normals[valid] @ up
    cand = valid[nu >= cos_n]
    # Samples that may join an upward plane: normal within tolerance, or no normal at all.
    pool = valid[(nu >= cos_n) | ~samples.has_normal[valid]]
    if len(cand) == 0:
        return []
    t = samples.points[cand] @ up
    peaks = histogram_peaks(t, samples.area[cand], -config.max_depth, config.max_depth, LAYER_BIN,
                            config.min_plane_area, LAYER_SEPARATION)
    taken = np.zeros(len(samples.valid), dtype=bool)
    layers = []
    for height, _ in peaks:
        near = np.abs(t - height) < samples.tolerance[cand]
        members = cand[near & ~taken[cand]]
        plane = _refit(samples, members)
        if plane is None or plane[:3] @ up < cos_n:
            continue
        open_pool = pool[~taken[pool]]
        inl = open_pool[_inliers(samples, plane, open_pool, config, allow_no_normal=True)]
        area = float(samples.area[inl].sum())
        if area < config.min_plane_area:
            continue
        taken[inl] = True
        layers.append((plane, inl, area))
    layers.sort(key=lambda x: -x[2])
    return layers


def vertical_planes(samples: CloudSamples, basis: HorizontalBasis, pool: np.ndarray, azimuth: np.ndarray,
                    loose: np.ndarray, config: SceneConfig) -> list[PlaneSegment]:
    """Vertical planes among ``pool`` (indices of free samples with a horizontal normal, whose
    azimuths [deg] are ``azimuth``): azimuth modes, then offset modes per azimuth. ``loose``:
    indices of free samples without a normal (edges, borders), which a plane takes when they
    lie within half its tolerance."""
    out: list[PlaneSegment] = []
    if len(pool) == 0:
        return out
    w = samples.area[pool]
    directions = histogram_peaks(azimuth, w, 0.0, 360.0, AZIMUTH_BIN, config.min_plane_area, AZIMUTH_SEPARATION, circular=True)
    alive = np.ones(len(pool), dtype=bool)
    loose_alive = np.ones(len(loose), dtype=bool)
    reach = config.plane_normal_angle_deg + AZIMUTH_BIN
    for direction, _ in directions:
        diff = np.abs((azimuth - direction + 180.0) % 360.0 - 180.0)
        # Samples this direction's planes may take (normal agreement is checked per plane) ...
        sub_pos = np.flatnonzero(alive & (diff < reach))
        # ... and the ones that vote for its offsets.
        voters = diff[sub_pos] < 0.5 * AZIMUTH_SEPARATION + AZIMUTH_BIN
        if w[sub_pos[voters]].sum() < config.min_plane_area:
            continue
        sub = pool[sub_pos]
        m = basis.direction(direction).astype(np.float32)
        s = samples.points[sub] @ m
        offsets = histogram_peaks(s[voters], w[sub_pos[voters]], -config.max_depth, config.max_depth, LAYER_BIN,
                                  config.min_plane_area, LAYER_SEPARATION)
        free_sub = np.ones(len(sub), dtype=bool)
        for offset, _ in offsets:
            members = sub[voters & free_sub & (np.abs(s - offset) < samples.tolerance[sub])]
            plane = _refit(samples, members)
            if plane is None:
                continue
            candidates = np.flatnonzero(free_sub)
            inl_pos = candidates[_inliers(samples, plane, sub[candidates], config)]
            loose_pos = np.flatnonzero(loose_alive)
            loose_pos = loose_pos[_inliers(samples, plane, loose[loose_pos], config, allow_no_normal=True)]
            pieces, kept = _pieces(samples, plane, np.concatenate([sub[inl_pos], loose[loose_pos]]), "vertical",
                                   config.min_plane_area)
            kept_sub, kept_loose = kept[:len(inl_pos)], kept[len(inl_pos):]
            free_sub[inl_pos[kept_sub]] = False
            alive[sub_pos[inl_pos[kept_sub]]] = False
            loose_alive[loose_pos[kept_loose]] = False
            out.extend(pieces)
    return out


def grow_planes(samples: CloudSamples, segments: list[PlaneSegment], free: np.ndarray, rounds: int = 2) -> list[np.ndarray]:
    """Give free samples at plane borders (edges and corners, where normals are unreliable) to
    a neighbouring segment's plane when within its tolerance: ``rounds`` passes over the 8
    image neighbours. Returns, per segment, the indices it gained; updates ``free``."""
    h, w = samples.shape
    gained: list[list[np.ndarray]] = [[] for _ in segments]
    if not segments:
        return [np.zeros(0, dtype=np.int64) for _ in segments]
    # Owners on a grid padded by one sample of -1 (no owner), so neighbours need no bounds checks.
    wp = w + 2
    owner_pad = np.full((h + 2, wp), -1, dtype=np.int32)
    owner2 = owner_pad[1:-1, 1:-1]
    owner = np.full(h * w, -1, dtype=np.int32)
    for k, seg in enumerate(segments):
        owner[seg.indices] = k
    owner2[...] = owner.reshape(h, w)
    owner_flat = owner_pad.reshape(-1)
    planes = np.array([seg.plane for seg in segments], dtype=np.float32)
    offsets = [dr * wp + dc for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc]
    kernel = np.ones((3, 3), np.uint8)
    for _ in range(rounds):
        # Only free samples next to an owned one can be taken.
        near = cv2.dilate((owner2 >= 0).view(np.uint8), kernel).reshape(-1)
        idx = np.flatnonzero(free & near.view(bool))
        if len(idx) == 0:
            break
        r, c = np.divmod(idx, w)
        pidx = (r + 1) * wp + (c + 1)
        n = len(idx)
        # Neighbour owners, one row per direction (in the order the directions are tried).
        K = owner_flat[pidx[None, :] + np.array(offsets)[:, None]]
        has = K >= 0
        if not has.any():
            break
        dirs, cols = np.nonzero(has)
        k = K[dirs, cols]
        pl = planes[k]
        at = idx[cols]
        d = np.abs(np.einsum("ij,ij->i", samples.points[at], pl[:, :3]) + pl[:, 3])
        D = np.full((len(offsets), n), np.inf, dtype=np.float32)
        ok = d < samples.tolerance[at]
        D[dirs[ok], cols[ok]] = d[ok]
        # The nearest plane within tolerance; ties go to the first direction tried.
        first = np.argmin(D, axis=0)
        won = np.isfinite(D[first, np.arange(n)])
        if not won.any():
            break
        best = K[first[won], np.flatnonzero(won)]
        won_idx = idx[won]
        owner_flat[pidx[won]] = best
        free[won_idx] = False
        order = np.argsort(best, kind="stable")
        ks, members = best[order], won_idx[order]
        bounds = np.searchsorted(ks, np.arange(len(segments) + 1))
        for k in range(len(segments)):
            if bounds[k + 1] > bounds[k]:
                gained[k].append(members[bounds[k]:bounds[k + 1]])
    return [np.concatenate(g) if g else np.zeros(0, dtype=np.int64) for g in gained]


def slanted_planes(samples: CloudSamples, pool: np.ndarray, config: SceneConfig, max_planes: int = 2,
                   hypotheses: int = 64, subset: int = 800, seed: int = 0) -> list[PlaneSegment]:
    """Up to ``max_planes`` more planes among ``pool`` (indices of free samples with normals),
    by RANSAC: ``hypotheses`` three-point planes scored on an evenly spaced ``subset`` by inlier
    area, the best refitted on all its inliers."""
    rng = np.random.default_rng(seed)
    out: list[PlaneSegment] = []
    cos_n = math.cos(math.radians(config.plane_normal_angle_deg))
    for _ in range(max_planes):
        if len(pool) < 30 or samples.area[pool].sum() < config.min_plane_area:
            break
        sub = pool[:: max(1, len(pool) // subset)]
        P = samples.points[sub]
        N = samples.normals[sub]
        A = samples.area[sub]
        T = samples.tolerance[sub]
        tri = rng.integers(0, len(sub), size=(hypotheses, 3))
        a, b, c = (P[tri[:, i]].astype(np.float64) for i in range(3))
        n = np.cross(b - a, c - a)
        norm = np.linalg.norm(n, axis=1)
        good = norm > 1e-9
        if not good.any():
            break
        n = n[good] / norm[good, None]
        d = -np.einsum("ij,ij->i", n, a[good])
        flip = d < 0
        n[flip] *= -1
        d[flip] *= -1
        n32 = n.T.astype(np.float32)
        dist = np.abs(P @ n32 + d.astype(np.float32))    # (subset, hypotheses)
        agree = (N @ n32) >= cos_n
        score = ((dist < T[:, None]) & agree).astype(np.float32).T @ A
        best = int(np.argmax(score))
        if score[best] * (len(pool) / len(sub)) < config.min_plane_area:
            break
        plane = _refit(samples, pool[_inliers(samples, np.array([*n[best], d[best]]), pool, config)])
        if plane is None:
            break
        ok = _inliers(samples, plane, pool, config)
        pieces, _ = _pieces(samples, plane, pool[ok], "slanted", config.min_plane_area)
        out.extend(pieces)
        pool = pool[~ok]
    return out
