"""The map seen from above: a floor-projected 2-D occupancy grid from the keyframes' depth (no ROS).

Needs a gravity-aligned map (M: z up, z = 0 on the floor). Every keyframe's depth (every 4th
pixel of its half-size image) is placed in M; a cell holding points between ``min_height`` and
``max_height`` above the floor (what a walker bumps into) is occupied, a cell where only floor
was seen is free, the rest unknown. A cell needs ``min_hits`` points to count, so isolated
depth noise does not become a wall. Obstacle points that the keyframes saw through more often
than they saw them — people who walked by — are left out
(:mod:`raspv_slam.static_obstacles`): only what stayed put is a wall.
"""
from __future__ import annotations

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.occupancy import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from raspv_slam.slam_map import SlamMap
from raspv_slam.static_obstacles import DepthView, visibility_evidence

RESOLUTION = 0.05           # m per cell (map_server maps of buildings: 0.05)
FLOOR_TOLERANCE = 0.05      # |z| below this is floor [m]
MIN_HEIGHT = 0.10           # obstacles: from here ... [m]
MAX_HEIGHT = 1.90           # ... to head height [m]
MIN_HITS = 3
STRIDE = 4
MARGIN = 0.5                # around what was seen [m]
MAX_EXTENT = 300.0          # a grid wider than this [m] keeps the square of this side round the points'
                            # median: a map whose keyframes flew off (lost tracking) must not write GBs


def keyframe_views(slam_map: SlamMap) -> tuple[list[DepthView], CameraIntrinsics]:
    """Every keyframe's depth of the first sub-map (the dense-registration size) with its pose
    M ← C, and that size's intrinsics. A sub-map not merged into it yet has a frame of its own
    (see :mod:`raspv_slam.slam_map`): left out."""
    K = slam_map.intrinsics.scaled(*_small_size(slam_map))
    poses = slam_map.poses()
    with slam_map.lock:
        world_from_slam = slam_map.world_from_slam.copy()
        keyframes = {k: kf for k, kf in slam_map.keyframes.items() if slam_map.segment.get(k, 0) == 0}
    views = [DepthView(world_from_slam @ poses[k], kf.images()[1]) for k, kf in keyframes.items()]
    return views, K


def points_of_views(views: list[DepthView], K: CameraIntrinsics, min_depth: float, max_depth: float,
                    stride: int = STRIDE) -> np.ndarray:
    """Depth points (every ``stride``-th pixel) of the views in M (N, 3)."""
    v, u = np.mgrid[0:K.height:stride, 0:K.width:stride]
    rays = K.rays(u, v).reshape(-1, 3)
    out = []
    for view in views:
        z = view.depth[::stride, ::stride].reshape(-1)
        ok = np.isfinite(z) & (z >= min_depth) & (z <= max_depth)
        T = view.map_from_camera
        out.append((rays[ok] * z[ok, None]) @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(out) if out else np.zeros((0, 3))


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


def occupancy_from_views(views: list[DepthView], K: CameraIntrinsics, min_depth: float, max_depth: float,
                         resolution: float = RESOLUTION) -> OccupancyGrid:
    """The occupancy grid of depth views in M, keeping only obstacles the views agree stayed put."""
    points = points_of_views(views, K, min_depth, max_depth)
    static = np.ones(len(points), bool)
    high = _obstacle_height(points[:, 2]) if len(points) else static
    static[high] = visibility_evidence(points[high], views, K, max_depth, voxel=resolution).static
    return occupancy_from_points(points, resolution, static)


def floor_occupancy(slam_map: SlamMap) -> OccupancyGrid:
    views, K = keyframe_views(slam_map)
    return occupancy_from_views(views, K, slam_map.config.min_depth, slam_map.config.max_depth)
