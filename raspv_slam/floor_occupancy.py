"""The map seen from above: a floor-projected 2-D occupancy grid from the keyframes' depth (no ROS).

Needs a gravity-aligned map (M: z up, z = 0 on the floor). Every keyframe's depth (every 4th
pixel of its half-size image) is placed in M; a cell holding points between ``min_height`` and
``max_height`` above the floor (what a walker bumps into) is occupied, a cell where only floor
was seen is free, the rest unknown. A cell needs ``min_hits`` points to count, so isolated
depth noise does not become a wall.
"""
from __future__ import annotations

import numpy as np

from raspv_common.occupancy import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from raspv_slam.slam_map import SlamMap

RESOLUTION = 0.05           # m per cell (map_server maps of buildings: 0.05)
FLOOR_TOLERANCE = 0.05      # |z| below this is floor [m]
MIN_HEIGHT = 0.10           # obstacles: from here ... [m]
MAX_HEIGHT = 1.90           # ... to head height [m]
MIN_HITS = 3
STRIDE = 4
MARGIN = 0.5                # around what was seen [m]
MAX_EXTENT = 300.0          # a grid wider than this [m] keeps the square of this side round the points'
                            # median: a map whose keyframes flew off (lost tracking) must not write GBs


def floor_points(slam_map: SlamMap, stride: int = STRIDE) -> np.ndarray:
    """Depth points of every keyframe of the first sub-map in M (N, 3). A sub-map not merged
    into it yet has a frame of its own (see :mod:`raspv_slam.slam_map`): left out."""
    K = slam_map.intrinsics.scaled(*_small_size(slam_map))
    poses = slam_map.poses()
    with slam_map.lock:
        world_from_slam = slam_map.world_from_slam.copy()
        keyframes = {k: kf for k, kf in slam_map.keyframes.items() if slam_map.segment.get(k, 0) == 0}
    v, u = np.mgrid[0:K.height:stride, 0:K.width:stride]
    rays = K.rays(u, v).reshape(-1, 3)
    out = []
    for k, kf in keyframes.items():
        _, depth = kf.images()
        z = depth[::stride, ::stride].reshape(-1)
        ok = np.isfinite(z) & (z >= slam_map.config.min_depth) & (z <= slam_map.config.max_depth)
        p = rays[ok] * z[ok, None]
        T = world_from_slam @ poses[k]
        out.append(p @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(out) if out else np.zeros((0, 3))


def _small_size(slam_map: SlamMap) -> tuple[int, int]:
    s = slam_map.config.dense_scale
    K = slam_map.intrinsics
    return max(8, int(round(K.width * s))), max(8, int(round(K.height * s)))


def occupancy_from_points(points: np.ndarray, resolution: float = RESOLUTION) -> OccupancyGrid:
    """Occupancy grid of points in a gravity-aligned frame (z up, z = 0 on the floor)."""
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
    obstacle = (z >= MIN_HEIGHT) & (z <= MAX_HEIGHT)
    counts_floor = np.zeros((rows, cols), np.int32)
    counts_obstacle = np.zeros((rows, cols), np.int32)
    np.add.at(counts_floor, (rc[floor, 0], rc[floor, 1]), 1)
    np.add.at(counts_obstacle, (rc[obstacle, 0], rc[obstacle, 1]), 1)
    grid.cells[counts_floor >= MIN_HITS] = FREE
    grid.cells[counts_obstacle >= MIN_HITS] = OCCUPIED
    return grid


def floor_occupancy(slam_map: SlamMap) -> OccupancyGrid:
    return occupancy_from_points(floor_points(slam_map))
