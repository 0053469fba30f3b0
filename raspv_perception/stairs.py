"""Staircase detection from one depth frame and its floor (no ROS): paper §III-D1 and §IV-B,
after Pérez-Yus et al. (ECCV-W 2014, CVIU 2017).

    detector = StairDetector(StairConfig())
    stair = detector.detect(depth_m, intrinsics, structure)     # structure: SceneStructure with a floor
    if stair is not None:
        stair.direction, stair.riser, stair.tread, stair.width, stair.camera_from_stair, stair.steps

How it works:

1. **Tread patches.** A sample is flat when the step to its image-row neighbour runs along the
   floor without rising (``max_slope``); risers and walls rise in place. Flat samples' heights
   above the floor pile up at the treads: each peak of the height histogram is rasterised on
   the floor plane (``cell`` m), closed over sampling gaps, opened by ``min_step_depth`` so the
   thin strips walls and risers still leave drop out, and split into connected pieces of at
   least ``min_step_area``. This sees the thin slivers a descending stair shows from its top,
   which whole-frame plane segmentation merges or drops.
2. **Levels.** Patches whose heights differ by ≤ ``level_merge`` and that touch (within
   ``connect_distance``) are one level. A chain starts at a level ``h_min``…``h_max`` above
   (ascending) or below (descending) the floor and next to visible floor, and climbs (or
   descends) one riser of ``h_min``…``h_max`` at a time to a touching level; the longest chain
   from each start is a candidate.
3. **Model.** The stair axes are the principal axes of the largest step or the Manhattan axes,
   whichever gives the smaller bounding box of all the steps; the walking direction points from
   the first step to the last. Riser = mean height difference between levels (the floor
   counts); tread = median distance between consecutive step edges (front edges when climbing,
   the far edges when going down — the near ones are hidden); width from the steps' extent
   along the edges. The model must satisfy ``h_min`` ≤ R ≤ ``h_max``, T ≥ ``min_tread`` and
   ``min_blondel`` ≤ 2R + T ≤ ``max_blondel`` (Blondel's rule).

Frames: camera optical frame C (x right, y down, z forward); floor frame F of
:mod:`raspv_perception.floor` (origin on the floor below the camera, y down, z forward); stair
frame S: origin at the middle of the first step's front edge (on the floor), y down, z
horizontal into the stair (walking direction), x = y × z. Metres.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import cv2
import numpy as np
from scipy.spatial import cKDTree

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.plane_fitting import histogram_peaks
from raspv_perception.point_cloud import organised_cloud
from raspv_perception.scene_structure import SceneStructure
from raspv_perception.stair_model import Staircase, StairDirection, StairStep


@dataclass(frozen=True)
class StairConfig:
    """Limits of a staircase (reference-facts: Pérez-Yus et al.) and of the tread search."""

    h_min: float = 0.09              # lowest riser [m]
    h_max: float = 0.225             # highest riser [m]
    min_tread: float = 0.22          # shortest tread [m]
    max_tread: float = 0.60          # longest tread between two steps [m]
    min_blondel: float = 0.40        # lower bound of 2R + T [m]
    max_blondel: float = 0.84        # upper bound of 2R + T [m]
    min_steps: int = 2               # steps (levels above/below the floor) needed for a staircase
    level_merge: float = 0.04        # patches closer than this in height are one level [m]
    connect_distance: float = 0.5    # neighbouring levels have points this close (floor plane) [m]
    height_tolerance: float = 0.02   # tread inlier band at 0 m, grows with z² like sensor noise [m]
    height_tolerance_quadratic: float = 0.003  # ... by this times z² [1/m]
    cell: float = 0.03               # floor-plane raster for tread patches [m]
    min_step_area: float = 0.04      # smallest tread patch [m²]
    min_step_depth: float = 0.06     # thinnest tread patch, either direction [m]
    max_slope: float = 0.25          # a tread sample rises less than this per metre to its row neighbour
    max_gap: float = 0.15            # ... which is nearer than this (no depth jump) [m]
    stride: int = 2                  # depth pixels between samples
    min_depth: float = 0.2           # nearer readings are ignored [m]
    max_depth: float = 6.0           # farther readings are ignored [m]

    def __post_init__(self) -> None:
        problems = []
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                problems.append(f"{f.name} must be a positive number, got {value!r}")
        if not problems:
            for lo, hi in (("h_min", "h_max"), ("min_tread", "max_tread"), ("min_blondel", "max_blondel"),
                           ("min_depth", "max_depth")):
                if getattr(self, lo) >= getattr(self, hi):
                    problems.append(f"{lo} ({getattr(self, lo)}) must be below {hi} ({getattr(self, hi)})")
            if self.level_merge >= self.h_min:
                problems.append(f"level_merge ({self.level_merge}) must be below h_min ({self.h_min})")
        if problems:
            raise ValueError("; ".join(problems))


@dataclass
class _Patch:
    height: float
    cells: np.ndarray        # (n, 2) occupied cell centres (x, z) in F
    area: float              # of the opened raster component [m²]
    points: np.ndarray       # (m, 2) the samples (x, z) in F


class StairDetector:
    """Detects the nearest valid staircase in a depth frame whose floor is known."""

    def __init__(self, config: StairConfig | None = None) -> None:
        self.config = config or StairConfig()

    def detect(self, depth: np.ndarray, intrinsics: CameraIntrinsics, structure: SceneStructure) -> Staircase | None:
        """The nearest staircase that passes the limits, or None (also without a floor)."""
        found = self.detect_all(depth, intrinsics, structure)
        return found[0] if found else None

    def detect_all(self, depth: np.ndarray, intrinsics: CameraIntrinsics,
                   structure: SceneStructure) -> list[Staircase]:
        """Every valid staircase, nearest first (an ascending and a descending one may share a
        view)."""
        if not structure.floor_found:
            return []
        cfg = self.config
        cloud = organised_cloud(depth, intrinsics, cfg.stride, cfg.min_depth, cfg.max_depth)
        T = structure.camera_to_floor
        R, t = T[:3, :3], T[:3, 3]
        grid_f = (cloud.points.astype(np.float64) - t) @ R      # (h, w, 3) in F: x, y (down), z
        flat = _flat_samples(grid_f, cfg.max_slope, cfg.max_gap) & cloud.valid
        if not flat.any():
            return []
        in_f = grid_f[flat]
        height = -in_f[:, 1]
        z_cam = cloud.points[flat][:, 2].astype(np.float64)
        tol = cfg.height_tolerance + cfg.height_tolerance_quadratic * z_cam ** 2
        patches = self._patches(in_f[:, [0, 2]], height, tol, cloud.footprint[flat].astype(np.float64))
        floor = self._floor_cells(in_f[:, [0, 2]], height, tol)
        if floor is None or not patches:
            return []
        found = []
        for sign, direction in ((1.0, StairDirection.ASCENDING), (-1.0, StairDirection.DESCENDING)):
            levels = self._levels([p for p in patches if sign * p.height > 0.5 * cfg.h_min])
            for chain in self._chains(levels, floor, sign):
                stair = self._model(chain, direction, structure)
                if stair is not None:
                    found.append(stair)
        found.sort(key=lambda s: s.distance)
        return _distinct(found)

    # -----------------------------------------------------------------------------------------
    def _patches(self, xz: np.ndarray, height: np.ndarray, tol: np.ndarray, weight: np.ndarray) -> list[_Patch]:
        cfg = self.config
        lo, hi = -4.0, 4.0
        peaks = histogram_peaks(height, weight, lo, hi, 0.01, min_weight=1e-3, separation=2 * cfg.level_merge)
        out = []
        for h, _ in peaks:
            if abs(h) < 0.5 * cfg.h_min:
                continue                                   # the floor itself
            sel = np.abs(height - h) <= tol
            out.extend(self._pieces(xz[sel], float(np.median(height[sel]))))
        return out

    def _floor_cells(self, xz: np.ndarray, height: np.ndarray, tol: np.ndarray) -> np.ndarray | None:
        """Centres (n, 2) of the floor-raster cells with floor samples, or None without floor."""
        sel = np.abs(height) <= tol
        if sel.sum() < 10:
            return None
        # one int per cell and a 1-D unique: 2 ms faster per frame than voxel_downsample, which
        # also computes the centroids and the inverse map this test does not need
        cell = self.config.cell
        ij = np.floor(xz[sel] / cell).astype(np.int64)
        key = np.unique((ij[:, 0] << 32) + (ij[:, 1] & 0xFFFFFFFF))
        i, j = key >> 32, (key & 0xFFFFFFFF).astype(np.int32).astype(np.int64)
        return (np.stack([i, j], axis=1) + 0.5) * cell

    def _pieces(self, xz: np.ndarray, height: float) -> list[_Patch]:
        """Connected pieces of one height band on the floor raster that are tread-shaped."""
        cfg = self.config
        if len(xz) < 4:
            return []
        k = int(math.ceil(cfg.min_step_depth / cfg.cell)) + 1
        pad = k + 2                                        # OpenCV pads erosions with 1s: keep off the border
        ij = np.floor(xz / cfg.cell).astype(np.int64)
        origin = ij.min(axis=0) - pad
        ij -= origin
        shape = tuple(int(v) for v in ij.max(axis=0) + pad + 1)
        if shape[0] * shape[1] > 4_000_000:                # far-off noise spread over a huge area
            return []
        grid = np.zeros((shape[1], shape[0]), np.uint8)
        grid[ij[:, 1], ij[:, 0]] = 1
        # close one-cell gaps between samples (stride × depth can exceed the cell when far), then
        # open by the thinnest tread: the strips walls and risers leave in the band vanish, and
        # so do the bits of them attached to a tread
        closed = cv2.morphologyEx(grid, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
        opened = cv2.morphologyEx(closed, cv2.MORPH_OPEN, np.ones((k, k), np.uint8))
        count, labels, stats, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
        point_label = labels[ij[:, 1], ij[:, 0]]
        cell_area = cfg.cell * cfg.cell
        out = []
        for c in range(1, count):
            if stats[c, cv2.CC_STAT_AREA] * cell_area < cfg.min_step_area:
                continue
            mask = labels == c
            rows, cols = np.nonzero(mask & (grid > 0))
            cells = (np.stack([cols, rows], axis=1) + origin + 0.5) * cfg.cell
            out.append(_Patch(height, cells, float(stats[c, cv2.CC_STAT_AREA] * cell_area), xz[point_label == c]))
        return out

    def _levels(self, patches: list[_Patch]) -> list[_Patch]:
        """Merge patches at the same height that touch (union-find)."""
        cfg = self.config
        n = len(patches)
        parent = list(range(n))

        def find(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        trees = [cKDTree(p.cells) for p in patches]
        for i in range(n):
            for j in range(i + 1, n):
                if abs(patches[i].height - patches[j].height) <= cfg.level_merge and \
                        _touch(trees[i], patches[j].cells, cfg.connect_distance):
                    parent[find(i)] = find(j)
        groups: dict[int, list[_Patch]] = {}
        for i in range(n):
            groups.setdefault(find(i), []).append(patches[i])
        levels = []
        for g in groups.values():
            area = np.array([p.area for p in g])
            levels.append(_Patch(float(np.average([p.height for p in g], weights=area)),
                                 np.concatenate([p.cells for p in g]), float(area.sum()),
                                 np.concatenate([p.points for p in g])))
        return levels

    def _chains(self, levels: list[_Patch], floor: np.ndarray, sign: float) -> list[list[_Patch]]:
        """The longest chain of levels from each first step (next to the floor)."""
        cfg = self.config
        if not levels:
            return []
        levels = sorted(levels, key=lambda p: sign * p.height)
        trees = [cKDTree(p.cells) for p in levels]
        n = len(levels)
        nxt: list[list[int]] = [[] for _ in range(n)]
        for i in range(n):
            for j in range(i + 1, n):
                rise = sign * (levels[j].height - levels[i].height)
                if cfg.h_min <= rise <= cfg.h_max and _touch(trees[i], levels[j].cells, cfg.connect_distance):
                    nxt[i].append(j)
        best: list[list[int]] = [[] for _ in range(n)]      # longest chain starting at i (DAG: i < j)
        for i in reversed(range(n)):
            tails = [best[j] for j in nxt[i]]
            best[i] = [i] + (max(tails, key=len) if tails else [])
        floor_tree = cKDTree(floor)
        starts = [i for i in range(n) if cfg.h_min <= sign * levels[i].height <= cfg.h_max
                  and _touch(floor_tree, levels[i].cells, cfg.connect_distance)]
        chains = [[levels[k] for k in best[i]] for i in starts]
        return [c for c in chains if len(c) >= cfg.min_steps]

    def _model(self, chain: list[_Patch], direction: StairDirection, structure: SceneStructure) -> Staircase | None:
        cfg = self.config
        w = self._walking_direction(chain, structure)
        if (chain[-1].cells @ w).mean() < (chain[0].cells @ w).mean():
            w = -w                                         # walking direction: first step → last
        x_s = np.array([w[1], -w[0]])                      # S x = y × z with y down, as (x, z) in F
        proj_w = [p.points @ w for p in chain]
        proj_u = [p.points @ x_s for p in chain]
        heights = np.array([p.height for p in chain])
        risers = np.abs(np.diff(np.concatenate([[0.0], heights])))
        riser = float(risers.mean())
        if direction == StairDirection.ASCENDING:
            fronts = np.array([np.percentile(pw, 1) for pw in proj_w])     # the nosing of each tread
            treads = np.diff(fronts)
        else:
            # the far edge of each tread; the last level's far edge is the end of the landing
            # (or of the view), not a step edge
            backs = np.array([np.percentile(pw, 99) for pw in proj_w])
            treads = np.diff(backs[:-1])
        if len(treads) == 0:
            return None
        tread = float(np.median(treads))                  # robust to an edge cut by the view
        if direction == StairDirection.DESCENDING:
            fronts = np.concatenate([[backs[0] - tread], backs[:-1]])
        if not (cfg.h_min <= riser <= cfg.h_max and cfg.min_tread <= tread <= cfg.max_tread
                and cfg.min_blondel <= 2 * riser + tread <= cfg.max_blondel):
            return None
        if (treads < 0.5 * cfg.min_tread).any():
            return None
        u_lo = np.array([np.percentile(pu, 0.5) for pu in proj_u])
        u_hi = np.array([np.percentile(pu, 99.5) for pu in proj_u])
        widths = u_hi - u_lo
        width = float(np.median(widths))
        u_mid = float(np.median(0.5 * (u_lo + u_hi)))
        origin_xz = u_mid * x_s + fronts[0] * w
        F_T_S = np.eye(4)
        F_T_S[:3, 0] = [x_s[0], 0.0, x_s[1]]
        F_T_S[:3, 1] = [0.0, 1.0, 0.0]
        F_T_S[:3, 2] = [w[0], 0.0, w[1]]
        F_T_S[:3, 3] = [origin_xz[0], 0.0, origin_xz[1]]
        C_T_S = structure.camera_to_floor @ F_T_S
        steps = []
        for k, h in enumerate(heights):
            z0 = fronts[k] - fronts[0]
            if direction == StairDirection.ASCENDING:
                measured = k + 1 < len(chain)
                depth = float(treads[k]) if measured else tread
            else:
                measured = k > 0
                depth = float(backs[k] - fronts[k]) if measured else tread
            wk = float(widths[k])
            corners_s = np.array([[-wk / 2, -h, z0], [wk / 2, -h, z0], [wk / 2, -h, z0 + depth], [-wk / 2, -h, z0 + depth]])
            corners_c = corners_s @ C_T_S[:3, :3].T + C_T_S[:3, 3]
            steps.append(StairStep(k, float(h), depth, wk, corners_c, measured))
        a = np.array([(u_mid - width / 2) * x_s + fronts[0] * w, (u_mid + width / 2) * x_s + fronts[0] * w])
        distance = _point_segment_distance(np.zeros(2), a[0], a[1])
        return Staircase(direction, C_T_S, riser, tread, width, distance, steps)

    def _walking_direction(self, chain: list[_Patch], structure: SceneStructure) -> np.ndarray:
        """Unit (x, z) vector in F across the step edges (sign not yet chosen): perpendicular to
        the edge direction u that boxes the steps tighter, the largest step's major axis or a
        Manhattan axis."""
        pts = np.concatenate([p.cells for p in chain])
        biggest = max(chain, key=lambda p: p.area).cells
        cov = np.cov((biggest - biggest.mean(axis=0)).T)
        _, vecs = np.linalg.eigh(cov)
        candidates = [vecs[:, 1]]                          # the major axis runs along the edges
        if structure.manhattan_found:
            R = structure.camera_to_floor[:3, :3]
            for axis in (structure.manhattan_x, structure.manhattan_z):
                a = R.T @ np.asarray(axis, dtype=np.float64)
                v = np.array([a[0], a[2]])
                if np.linalg.norm(v) > 0.5:
                    candidates.append(v / np.linalg.norm(v))

        def box_area(u: np.ndarray) -> float:
            w = np.array([-u[1], u[0]])
            pu, pw = pts @ u, pts @ w
            return float((pu.max() - pu.min()) * (pw.max() - pw.min()))

        u = min(candidates, key=box_area)
        u = u / np.linalg.norm(u)
        return np.array([-u[1], u[0]])


def _flat_samples(grid_f: np.ndarray, max_slope: float, max_gap: float) -> np.ndarray:
    """(h, w) bool: samples on a horizontal surface. Going down one image row on a tread moves
    along the floor without changing height; on a riser or a wall it changes height in place.
    A sample is flat when the step to its upper or lower neighbour rises less than
    ``max_slope`` × its run and that run is under ``max_gap`` m (no depth jump)."""
    d = np.diff(grid_f, axis=0)                              # (h−1, w, 3)
    rise = np.abs(d[..., 1])
    run = np.hypot(d[..., 0], d[..., 2])
    with np.errstate(invalid="ignore"):
        ok = (rise <= max_slope * run) & (run <= max_gap)
    flat = np.zeros(grid_f.shape[:2], dtype=bool)
    flat[:-1] |= ok
    flat[1:] |= ok
    return flat


def _touch(tree: cKDTree, cells: np.ndarray, distance: float) -> bool:
    d, _ = tree.query(cells, k=1, distance_upper_bound=distance)
    return bool(np.isfinite(d).any())


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    s = float(np.clip((p - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + s * ab)))


def _distinct(stairs: list[Staircase]) -> list[Staircase]:
    """Drop chains that describe a staircase already listed (same direction, origin within a
    tread): a chain from a higher first step is the same stair seen partly."""
    out: list[Staircase] = []
    for s in stairs:
        if not any(o.direction == s.direction and
                   np.linalg.norm(o.camera_from_stair[:3, 3] - s.camera_from_stair[:3, 3]) < o.tread for o in out):
            out.append(s)
    return out
