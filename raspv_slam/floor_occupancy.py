"""The map seen from above: a floor-projected 2-D occupancy grid from the keyframes' depth (no ROS).

Needs a gravity-aligned map (M: z up, z = 0 on the floor). Every keyframe's depth (every 4th
pixel of its half-size image) is placed in M; a cell holding points between ``min_height`` and
``max_height`` above the floor (what a walker bumps into) is occupied, a cell where only floor
was seen is free, the rest unknown. A cell needs ``min_hits`` points to count, so isolated
depth noise does not become a wall. Obstacle points that the keyframes saw through more often
than they saw them — people who walked by — are left out
(:mod:`raspv_slam.static_obstacles`): only what stayed put is a wall.

Memory is bounded by the mapped area, not by the keyframes: the keyframes' depth images are
decoded one at a time, twice (once to count points per cell and per 5-cm voxel, once to let
every keyframe vote on the voxels within its reach), never all at once — a 10-minute walk's map
holds thousands of keyframes (0.3 MB of decoded depth each).
"""
from __future__ import annotations

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.occupancy import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from raspv_slam.slam_map import SlamMap
from raspv_slam.static_obstacles import DepthView, judge_view, reach

RESOLUTION = 0.05           # m per cell (map_server maps of buildings: 0.05)
FLOOR_TOLERANCE = 0.05      # |z| below this is floor [m]
MIN_HEIGHT = 0.10           # obstacles: from here ... [m]
MAX_HEIGHT = 1.90           # ... to head height [m]
MIN_HITS = 3
STRIDE = 4
MARGIN = 0.5                # around what was seen [m]
BATCH_ROWS = 1 << 15         # points counted per merge (and at most as many as the counts hold)
MAX_EXTENT = 300.0          # a grid wider than this [m] keeps the square of this side round the points'
                            # median: a map whose keyframes flew off (lost tracking) must not write GBs


class KeyframeDepthViews:
    """The keyframes' depth views, decoded one at a time as they are iterated (each iteration
    decodes afresh: nothing is kept)."""

    def __init__(self, poses: list[np.ndarray], keyframes: list) -> None:
        self._poses, self._keyframes = poses, keyframes

    def __len__(self) -> int:
        return len(self._keyframes)

    def __iter__(self):
        for pose, kf in zip(self._poses, self._keyframes):
            yield DepthView(pose, kf.images()[1])


def keyframe_views(slam_map: SlamMap) -> tuple[KeyframeDepthViews, CameraIntrinsics]:
    """Every keyframe's depth of the first sub-map (the dense-registration size) with its pose
    M ← C, and that size's intrinsics. A sub-map not merged into it yet has a frame of its own
    (see :mod:`raspv_slam.slam_map`): left out."""
    K = slam_map.intrinsics.scaled(*_small_size(slam_map))
    poses = slam_map.poses()
    with slam_map.lock:
        world_from_slam = slam_map.world_from_slam.copy()
        keyframes = {k: kf for k, kf in slam_map.keyframes.items() if slam_map.segment.get(k, 0) == 0}
    return KeyframeDepthViews([world_from_slam @ poses[k] for k in keyframes], list(keyframes.values())), K


def points_of_views(views, K: CameraIntrinsics, min_depth: float, max_depth: float,
                    stride: int = STRIDE) -> np.ndarray:
    """Depth points (every ``stride``-th pixel) of the views in M (N, 3)."""
    out = [points_of_view(view, K, min_depth, max_depth, stride) for view in views]
    return np.concatenate(out) if out else np.zeros((0, 3))


def points_of_view(view: DepthView, K: CameraIntrinsics, min_depth: float, max_depth: float,
                   stride: int = STRIDE) -> np.ndarray:
    """Depth points (every ``stride``-th pixel) of one view in M (N, 3)."""
    v, u = np.mgrid[0:K.height:stride, 0:K.width:stride]
    rays = K.rays(u, v).reshape(-1, 3)
    z = view.depth[::stride, ::stride].reshape(-1)
    ok = np.isfinite(z) & (z >= min_depth) & (z <= max_depth)
    T = view.map_from_camera
    return (rays[ok] * z[ok, None]) @ T[:3, :3].T + T[:3, 3]


def floor_points(slam_map: SlamMap, stride: int = STRIDE) -> np.ndarray:
    """Depth points of every keyframe of the first sub-map in M (N, 3)."""
    views, K = keyframe_views(slam_map)
    return points_of_views(views, K, slam_map.config.min_depth, slam_map.config.max_depth, stride)


def _small_size(slam_map: SlamMap) -> tuple[int, int]:
    s = slam_map.config.dense_scale
    K = slam_map.intrinsics
    return max(8, int(round(K.width * s))), max(8, int(round(K.height * s)))


def occupancy_from_points(points: np.ndarray, resolution: float = RESOLUTION,
                          static: np.ndarray | None = None) -> OccupancyGrid:
    """Occupancy grid of points in a gravity-aligned frame (z up, z = 0 on the floor); with
    ``static`` (N,) bool, only static points make obstacles (a moving one's floor stays free)."""
    if static is not None:
        points = np.asarray(points)[np.asarray(static, bool) | ~_obstacle_height(np.asarray(points)[:, 2])]
    if not len(points):
        return OccupancyGrid(np.full((1, 1), UNKNOWN, np.int8), resolution, (0.0, 0.0))
    if np.any(np.ptp(points[:, :2], axis=0) > MAX_EXTENT - 2 * MARGIN):
        centre = np.median(points[:, :2], axis=0)
        points = points[np.all(np.abs(points[:, :2] - centre) <= MAX_EXTENT / 2 - MARGIN, axis=1)]
    lo = np.floor((points[:, :2].min(axis=0) - MARGIN) / resolution) * resolution
    hi = points[:, :2].max(axis=0) + MARGIN
    cols, rows = (np.ceil((hi - lo) / resolution).astype(int) + 1)
    grid = OccupancyGrid(np.full((rows, cols), UNKNOWN, np.int8), resolution, (float(lo[0]), float(lo[1])))
    rc = grid.world_to_cell(points[:, :2])
    z = points[:, 2]
    floor = np.abs(z) < FLOOR_TOLERANCE
    obstacle = _obstacle_height(z)
    counts_floor = np.zeros((rows, cols), np.int32)
    counts_obstacle = np.zeros((rows, cols), np.int32)
    np.add.at(counts_floor, (rc[floor, 0], rc[floor, 1]), 1)
    np.add.at(counts_obstacle, (rc[obstacle, 0], rc[obstacle, 1]), 1)
    grid.cells[counts_floor >= MIN_HITS] = FREE
    grid.cells[counts_obstacle >= MIN_HITS] = OCCUPIED
    return grid


def _obstacle_height(z: np.ndarray) -> np.ndarray:
    return (z >= MIN_HEIGHT) & (z <= MAX_HEIGHT)


def occupancy_from_views(views, K: CameraIntrinsics, min_depth: float, max_depth: float,
                         resolution: float = RESOLUTION) -> OccupancyGrid:
    """The occupancy grid of depth views in M (any re-iterable of :class:`DepthView`: it is
    walked twice), keeping only obstacles the views agree stayed put.

    Streamed: points are counted per grid cell (floor, the rest) and per voxel (obstacle height;
    voxels of the grid's size, so each lies in one cell) view by view; then every view votes on
    the voxels within its reach; a static voxel's points count for its cell. The grid is the one
    :func:`occupancy_from_points` makes of the points and their static flags, its margin counted
    from the outermost cell instead of the outermost point."""
    floor_cells, other_cells = _Counts(2), _Counts(2)
    voxels = _Counts(3, sums=True)
    for view in views:
        p = points_of_view(view, K, min_depth, max_depth)
        cell = np.floor(p[:, :2] / resolution).astype(np.int64)
        floor = np.abs(p[:, 2]) < FLOOR_TOLERANCE
        high = _obstacle_height(p[:, 2])
        floor_cells.add(cell[floor])
        other_cells.add(cell[~floor & ~high])
        voxels.add(np.floor(p[high] / resolution).astype(np.int64), p[high])
    vox_keys, vox_counts, vox_sums = voxels.result()
    static = np.ones(len(vox_keys), bool)
    if len(vox_keys):
        from scipy.spatial import cKDTree

        centres = (vox_sums / vox_counts[:, None]).astype(np.float32)      # the mean point: on the surface
        seen = np.zeros(len(vox_keys), np.int32)
        through = np.zeros(len(vox_keys), np.int32)
        tree, radius = cKDTree(centres[:, :2]), reach(K, max_depth)
        for view in views:
            near = np.asarray(tree.query_ball_point(view.map_from_camera[:2, 3], radius), np.int64)
            if len(near):
                judge_view(centres, view, K, max_depth, seen, through, voxel=resolution, candidates=np.sort(near))
        static = through <= seen
    f_keys, f_counts, _ = floor_cells.result()
    o_keys, o_counts, _ = other_cells.result()
    s_keys, s_counts = vox_keys[static, :2], vox_counts[static]
    every = np.concatenate([f_keys, o_keys, s_keys])
    if not len(every):
        return OccupancyGrid(np.full((1, 1), UNKNOWN, np.int8), resolution, (0.0, 0.0))
    weights = np.concatenate([f_counts, o_counts, s_counts])
    half = int(round((MAX_EXTENT / 2 - MARGIN) / resolution))
    if np.any(np.ptp(every, axis=0) * resolution > MAX_EXTENT - 2 * MARGIN):
        centre = np.array([_weighted_median(every[:, i], weights) for i in range(2)])
        keep = np.all(np.abs(every - centre) <= half, axis=1)
        every = every[keep]
    margin = int(np.ceil(MARGIN / resolution))
    lo = every.min(axis=0) - margin
    cols, rows = every.max(axis=0) + margin - lo + 1
    grid = OccupancyGrid(np.full((rows, cols), UNKNOWN, np.int8), resolution,
                         (float(lo[0] * resolution), float(lo[1] * resolution)))
    for keys, counts, value in ((f_keys, f_counts, FREE), (s_keys, s_counts, OCCUPIED)):
        per_cell = np.zeros((rows, cols), np.int64)
        rc = keys[:, ::-1] - lo[::-1]
        inside = grid.inside(rc)
        np.add.at(per_cell, (rc[inside, 0], rc[inside, 1]), counts[inside])
        grid.cells[per_cell >= MIN_HITS] = value
    return grid


class _Counts:
    """Integer keys (N, d) counted (and, with ``sums``, their points summed) in bounded memory:
    batches are merged by :func:`numpy.unique` once they hold as many rows as the result."""

    def __init__(self, dims: int, sums: bool = False) -> None:
        self.dims, self.sums = dims, sums
        self._keys = np.zeros((0, dims), np.int64)
        self._counts = np.zeros(0, np.int64)
        self._sums = np.zeros((0, 3))
        self._pending: list[tuple] = []
        self._pending_rows = 0

    def add(self, keys: np.ndarray, points: np.ndarray | None = None) -> None:
        if len(keys):
            self._pending.append((keys, np.ones(len(keys), np.int64), points))
            self._pending_rows += len(keys)
            if self._pending_rows > max(len(self._keys), BATCH_ROWS):
                self._merge()

    def _merge(self) -> None:
        if not self._pending:
            return
        keys = np.concatenate([self._keys] + [k for k, _, _ in self._pending])
        counts = np.concatenate([self._counts] + [c for _, c, _ in self._pending])
        unique, inverse = np.unique(keys, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        if self.sums:
            points = np.concatenate([self._sums] + [p for _, _, p in self._pending])
            self._sums = np.stack([np.bincount(inverse, points[:, i], len(unique)) for i in range(3)], axis=1)
        self._keys, self._counts = unique, np.bincount(inverse, counts, len(unique)).astype(np.int64)
        self._pending, self._pending_rows = [], 0

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(unique keys (M, d), their counts (M,), the sums of their points (M, 3))."""
        self._merge()
        return self._keys, self._counts, self._sums


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    order = np.argsort(values, kind="stable")
    cumulative = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cumulative, cumulative[-1] / 2)])


def floor_occupancy(slam_map: SlamMap) -> OccupancyGrid:
    views, K = keyframe_views(slam_map)
    return occupancy_from_views(views, K, slam_map.config.min_depth, slam_map.config.max_depth)
