"""Placing a SLAM map on a 2-D building map without a tape measure (no ROS).

The paper aligned its RGB-D SLAM map to the laser-scanned building map by hand (Fig. 13). Here
the floor-projected occupancy of a saved SLAM map (frame M: gravity-aligned, z up, metres) is
registered to a building's occupancy grid (frame B, map_server YAML + PGM) as a planar rigid
transform B ← M (x, y, yaw):

1. **Likelihood field** of the building: every cell scores exp(−d²/2σ²), d its distance to the
   nearest building wall (scan matching's likelihood field, Thrun et al., *Probabilistic
   Robotics* §6.4). A placement's score is the mean field value under the SLAM map's occupied
   cells, minus ``free_weight`` × the share of the SLAM map's *free* cells (floor it saw) that fall
   on building walls — a map cannot have walked through a wall.
2. **Exhaustive search** over yaw (every ``yaw_step_deg``) and, for each yaw, every translation
   at once: the rotated SLAM cells are rasterised and cross-correlated with the field by FFT
   (``scipy.fft``; the building's transforms computed once), on grids of ``search_resolution``.
3. **Refinement** of the best distinct placements (non-maximum suppression in x, y, yaw) on the
   full-resolution field, continuous in x, y, yaw (bilinear field, Nelder–Mead, scipy).
4. **Ambiguity**: when the best placement that is distinct from the winner (farther than
   ``distinct_m`` or turned more than ``distinct_deg``) scores ≥ ``ambiguity_ratio`` of it — a
   symmetric corridor, a map that saw too little — the alignment is refused
   (:class:`AmbiguousAlignment` names both); a rough guess (``guess``: x, y, yaw with a radius)
   restricts the search and settles it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import fft, ndimage, optimize

from raspv_common.occupancy import FREE, OCCUPIED, OccupancyGrid


REFINE_POINTS = 4000        # cells of each kind scored while refining (the search uses all)


class AlignmentError(ValueError):
    """The SLAM map cannot be placed on the building map (the message says why)."""


class AmbiguousAlignment(AlignmentError):
    """Two distinct placements score alike; ``best`` and ``runner_up`` are the candidates."""

    def __init__(self, message: str, best: "BuildingAlignment", runner_up: "BuildingAlignment"):
        super().__init__(message)
        self.best = best
        self.runner_up = runner_up


@dataclass(frozen=True)
class AlignmentConfig:
    sigma: float = 0.10                 # likelihood field width [m]
    search_resolution: float = 0.10     # grid of the exhaustive search [m]
    yaw_step_deg: float = 2.0           # yaw step of the exhaustive search
    free_weight: float = 0.5            # weight of "free cells on building walls"
    candidates: int = 6                 # distinct placements refined
    distinct_m: float = 1.0             # placements farther apart than this are distinct ...
    distinct_deg: float = 15.0          # ... or turned more than this
    ambiguity_ratio: float = 0.85       # runner-up / best ≥ this: ambiguous
    min_score: float = 0.25             # a best score below this is no match
    max_points: int = 20000             # SLAM cells used (subsampled beyond) for speed

    def __post_init__(self) -> None:
        if self.sigma <= 0 or self.search_resolution <= 0 or self.yaw_step_deg <= 0:
            raise ValueError("sigma, search_resolution and yaw_step_deg must be positive")
        if not 0 < self.ambiguity_ratio <= 1:
            raise ValueError(f"ambiguity_ratio must be in (0, 1], got {self.ambiguity_ratio}")


@dataclass(frozen=True)
class AlignmentGuess:
    """A rough placement of M on B: (x, y) [m] and yaw [deg] of M's origin and x axis in B,
    searched within ``radius`` [m] and ``yaw_range_deg`` either side."""

    x: float
    y: float
    yaw_deg: float
    radius: float = 2.0
    yaw_range_deg: float = 30.0


@dataclass(frozen=True)
class BuildingAlignment:
    """B ← M: M's origin at (x, y) [m] in B, its x axis at ``yaw_deg`` [deg, −180..180]; ``score`` the
    placement's score (see the module docstring), ``matched`` the share of the SLAM map's occupied
    cells within 2σ of a building wall, ``runner_up_score`` the best distinct placement's score."""

    x: float
    y: float
    yaw_deg: float
    score: float
    matched: float
    runner_up_score: float = 0.0

    def matrix(self) -> np.ndarray:
        """4×4 B ← M (planar: z and gravity unchanged)."""
        c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        T = np.eye(4)
        T[:2, :2] = [[c, -s], [s, c]]
        T[:2, 3] = (self.x, self.y)
        return T

    def as_dict(self) -> dict:
        return {"x": round(self.x, 4), "y": round(self.y, 4), "yaw_deg": round(self.yaw_deg, 3),
                "score": round(self.score, 4), "matched": round(self.matched, 4),
                "runner_up_score": round(self.runner_up_score, 4)}

    @classmethod
    def from_dict(cls, data: dict) -> "BuildingAlignment":
        try:
            return cls(float(data["x"]), float(data["y"]), float(data["yaw_deg"]), float(data.get("score", 0.0)),
                       float(data.get("matched", 0.0)), float(data.get("runner_up_score", 0.0)))
        except (KeyError, TypeError, ValueError) as exc:
            raise AlignmentError(f"building alignment needs numbers x, y, yaw_deg ({exc})") from None


# -- fields ---------------------------------------------------------------------------------

@dataclass
class _Field:
    """A per-cell field on a grid: value at world points by bilinear interpolation."""

    values: np.ndarray
    resolution: float
    origin: np.ndarray             # (x, y) of cell (0, 0)'s lower-left corner

    def at(self, xy: np.ndarray) -> np.ndarray:
        col = (xy[:, 0] - self.origin[0]) / self.resolution - 0.5
        row = (xy[:, 1] - self.origin[1]) / self.resolution - 0.5
        return ndimage.map_coordinates(self.values, [row, col], order=1, mode="constant", cval=0.0)


def _walls(grid: OccupancyGrid, resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """Occupied mask of ``grid`` resampled to ``resolution`` (a coarse cell is occupied if any
    fine cell in it is) and that grid's origin."""
    occ = grid.cells == OCCUPIED
    k = max(1, int(round(resolution / grid.resolution)))
    if k > 1:
        rows, cols = -(-occ.shape[0] // k) * k, -(-occ.shape[1] // k) * k
        padded = np.zeros((rows, cols), bool)
        padded[:occ.shape[0], :occ.shape[1]] = occ
        occ = padded.reshape(rows // k, k, cols // k, k).any(axis=(1, 3))
    return occ, np.asarray(grid.origin, dtype=float)


def _likelihood(walls: np.ndarray, resolution: float, sigma: float) -> np.ndarray:
    if not walls.any():
        raise AlignmentError("the building map has no occupied cells (walls) to align to")
    d = ndimage.distance_transform_edt(~walls) * resolution
    return np.exp(-0.5 * (d / sigma) ** 2)


def _cells(grid: OccupancyGrid, value: int, limit: int, rng: np.random.Generator) -> np.ndarray:
    """Centres of the cells holding ``value`` (at most ``limit``), in random order."""
    rc = rng.permutation(np.argwhere(grid.cells == value))[:limit]
    return grid.cell_to_world(rc) if len(rc) else np.zeros((0, 2))


def _rotate(xy: np.ndarray, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return xy @ np.array([[c, s], [-s, c]])


# -- search ---------------------------------------------------------------------------------

def align_to_building(slam_grid: OccupancyGrid, building: OccupancyGrid, guess: AlignmentGuess | None = None,
                      config: AlignmentConfig | None = None) -> BuildingAlignment:
    """B ← M placing ``slam_grid`` (M) on ``building`` (B). Raises :class:`AmbiguousAlignment`
    when two distinct placements score alike, :class:`AlignmentError` when nothing matches."""
    cfg = config or AlignmentConfig()
    rng = np.random.default_rng(0)
    occ = _cells(slam_grid, OCCUPIED, cfg.max_points, rng)
    free = _cells(slam_grid, FREE, cfg.max_points, rng)
    if len(occ) < 20:
        raise AlignmentError(f"the SLAM map has {len(occ)} occupied cells: too few walls or obstacles seen to align "
                             "(map more of the building)")
    # fine fields for refinement, coarse ones for the search
    fine_walls, fine_origin = _walls(building, building.resolution)
    fine = _Field(_likelihood(fine_walls, building.resolution, cfg.sigma), building.resolution, fine_origin)
    fine_wall_field = _Field(fine_walls.astype(float), building.resolution, fine_origin)
    r = max(cfg.search_resolution, building.resolution)
    coarse_walls, coarse_origin = _walls(building, r)
    coarse_res = building.resolution * max(1, int(round(r / building.resolution)))
    L = _likelihood(coarse_walls, coarse_res, max(cfg.sigma, coarse_res))
    W = coarse_walls.astype(float)

    if guess is None:
        yaws = np.arange(0.0, 360.0, cfg.yaw_step_deg)
    else:
        span = max(cfg.yaw_step_deg, guess.yaw_range_deg)
        yaws = guess.yaw_deg + np.arange(-span, span + 1e-9, cfg.yaw_step_deg)
    # every rotation of the SLAM cells fits a D × D raster round their centroid, so the building's
    # fields are transformed once; per yaw: two forward FFTs and one inverse
    centre = occ.mean(axis=0)
    radius = float(np.max(np.hypot(*(np.concatenate([occ, free]) - centre).T)))
    D = int(math.ceil(2 * radius / coarse_res)) + 2
    shape = (fft.next_fast_len(L.shape[0] + D - 1), fft.next_fast_len(L.shape[1] + D - 1))
    FL = fft.rfft2(L, shape)
    FW = fft.rfft2(W, shape)
    lo = centre - (D // 2) * coarse_res
    rows = np.arange(shape[0]) - (D - 1)              # output row k ↔ offset o = k − (D − 1) cells
    cols = np.arange(shape[1]) - (D - 1)
    ty_all = coarse_origin[1] + rows * coarse_res - lo[1]
    tx_all = coarse_origin[0] + cols * coarse_res - lo[0]
    tx_grid, ty_grid = np.meshgrid(tx_all, ty_all)
    found: list[tuple[float, float, float, float]] = []       # (score, x, y, yaw_deg)
    for yaw_deg in yaws:
        yaw = math.radians(yaw_deg)
        inside = np.ones(shape, bool)
        if guess is not None:          # M's origin in B is the raster's shift + (centre − R centre)
            offset = centre - _rotate(centre[None], yaw)[0]
            inside = np.hypot(tx_grid + offset[0] - guess.x, ty_grid + offset[1] - guess.y) <= guess.radius
        spectrum = FL * np.conj(fft.rfft2(_raster(_rotate(occ - centre, yaw) + centre, lo, coarse_res, (D, D)),
                                          shape)) / len(occ)
        if len(free):
            spectrum -= cfg.free_weight * FW * np.conj(fft.rfft2(
                _raster(_rotate(free - centre, yaw) + centre, lo, coarse_res, (D, D)), shape)) / len(free)
        score = np.roll(fft.irfft2(spectrum, shape), (D - 1, D - 1), axis=(0, 1))
        score = np.where(inside, score, -np.inf)
        for k in _local_maxima(score, 3):
            # the raster turned about the centroid: translation of the rotation about M's origin
            t = np.array([tx_grid.flat[k], ty_grid.flat[k]]) + centre - _rotate(centre[None], yaw)[0]
            found.append((float(score.flat[k]), float(t[0]), float(t[1]), float(yaw_deg % 360.0)))
    found.sort(reverse=True)
    distinct = _suppress(found, cfg.distinct_m, cfg.distinct_deg, cfg.candidates)
    if not distinct:
        raise AlignmentError("no placement of the SLAM map inside the building map (the guess region is empty?)")
    r_occ, r_free = occ[:REFINE_POINTS], free[:REFINE_POINTS]          # (already shuffled)
    refined = sorted((_refine(c, r_occ, r_free, fine, fine_wall_field, cfg) for c in distinct),
                     key=lambda a: a.score, reverse=True)
    best = refined[0]
    rivals = [a for a in refined[1:] if _far(a, best, cfg)]
    runner = rivals[0] if rivals else None
    best = BuildingAlignment(best.x, best.y, best.yaw_deg, best.score, best.matched,
                             runner.score if runner else 0.0)
    if best.score < cfg.min_score:
        raise AlignmentError(f"no placement matches: the best scores {best.score:.2f} (< {cfg.min_score}); "
                             f"{best.matched:.0%} of the SLAM map's walls lie on building walls")
    if runner is not None and runner.score >= cfg.ambiguity_ratio * best.score:
        raise AmbiguousAlignment(
            f"ambiguous: placements ({best.x:.2f}, {best.y:.2f}, {best.yaw_deg:.1f}°) and "
            f"({runner.x:.2f}, {runner.y:.2f}, {runner.yaw_deg:.1f}°) score {best.score:.3f} and {runner.score:.3f}; "
            "give a rough guess (x, y, yaw) to choose", best, runner)
    return best


def _raster(xy: np.ndarray, lo: np.ndarray, res: float, shape: tuple[int, int] | None = None) -> np.ndarray:
    idx = np.floor((xy - lo) / res).astype(int)
    rows = shape[0] if shape else int(idx[:, 1].max()) + 1
    cols = shape[1] if shape else int(idx[:, 0].max()) + 1
    ok = (idx[:, 0] >= 0) & (idx[:, 0] < cols) & (idx[:, 1] >= 0) & (idx[:, 1] < rows)
    out = np.zeros((rows, cols))
    np.add.at(out, (idx[ok, 1], idx[ok, 0]), 1.0)
    return out


def _local_maxima(score: np.ndarray, n: int) -> list[int]:
    """Flat indices of the ``n`` best local maxima of ``score``."""
    flat = score.reshape(-1)
    peaks = (score == ndimage.maximum_filter(score, size=9)).reshape(-1) & np.isfinite(flat)
    idx = np.flatnonzero(peaks)
    return list(idx[np.argsort(flat[idx])[::-1][:n]])


def _angle_diff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def _far(a, b, cfg: AlignmentConfig) -> bool:
    ax, ay, ayaw = (a.x, a.y, a.yaw_deg) if isinstance(a, BuildingAlignment) else a[1:]
    bx, by, byaw = (b.x, b.y, b.yaw_deg) if isinstance(b, BuildingAlignment) else b[1:]
    return math.hypot(ax - bx, ay - by) > cfg.distinct_m or _angle_diff(ayaw, byaw) > cfg.distinct_deg


def _suppress(found, distinct_m: float, distinct_deg: float, n: int):
    cfg = AlignmentConfig(distinct_m=distinct_m, distinct_deg=distinct_deg)
    kept: list = []
    for cand in found:
        if not math.isfinite(cand[0]):
            continue
        if all(_far(cand, k, cfg) for k in kept):
            kept.append(cand)
            if len(kept) == n:
                break
    return kept


def _placement_score(params, occ, free, field: _Field, walls: _Field, cfg: AlignmentConfig) -> tuple[float, float]:
    x, y, yaw_deg = params
    yaw = math.radians(yaw_deg)
    q = _rotate(occ, yaw) + (x, y)
    values = field.at(q)
    score = float(values.mean())
    if len(free):
        score -= cfg.free_weight * float(walls.at(_rotate(free, yaw) + (x, y)).mean())
    matched = float((values > math.exp(-2.0)).mean())          # within 2σ of a wall
    return score, matched


def _refine(cand, occ, free, field: _Field, walls: _Field, cfg: AlignmentConfig) -> BuildingAlignment:
    _, x0, y0, yaw0 = cand
    result = optimize.minimize(lambda p: -_placement_score(p, occ, free, field, walls, cfg)[0],
                               np.array([x0, y0, yaw0]), method="Nelder-Mead",
                               options={"xatol": 0.005, "fatol": 1e-5, "initial_simplex":
                                        np.array([[x0, y0, yaw0], [x0 + 0.1, y0, yaw0], [x0, y0 + 0.1, yaw0],
                                                  [x0, y0, yaw0 + 1.5]])})
    x, y, yaw = result.x
    score, matched = _placement_score(result.x, occ, free, field, walls, cfg)
    return BuildingAlignment(float(x), float(y), math.remainder(float(yaw), 360.0), score, matched)   # in [-180, 180]
