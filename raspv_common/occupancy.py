"""2-D occupancy grids in the map_server format (PGM + YAML), no rclpy.

Frames: the grid lives in the world frame W (x, y on the floor, metres). Cell (row, col) has
its centre at ``origin + ((col + 0.5)·res, (row + 0.5)·res)`` with row 0 at the *bottom* (the
PGM's last line), as ROS's map_server reads images. ``origin`` yaw must be 0.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from raspv_common.image_files import decode_image_file
from raspv_common.text_files import read_yaml_file

FREE, OCCUPIED, UNKNOWN = 0, 100, -1


class MapFormatError(ValueError):
    """A map YAML/image pair that cannot be read; the message names the file and the key."""


@dataclass
class OccupancyGrid:
    """``cells`` (rows, cols) int8: 0 free, 100 occupied, -1 unknown; ``resolution`` m/cell;
    ``origin`` (x, y) of the lower-left corner of cell (0, 0) in W [m]."""

    cells: np.ndarray
    resolution: float
    origin: tuple[float, float]

    @property
    def shape(self) -> tuple[int, int]:
        return self.cells.shape

    def world_to_cell(self, xy: np.ndarray) -> np.ndarray:
        """World points (N, 2) → integer (row, col) (N, 2); may fall outside the grid."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        col = np.floor((xy[:, 0] - self.origin[0]) / self.resolution).astype(int)
        row = np.floor((xy[:, 1] - self.origin[1]) / self.resolution).astype(int)
        return np.stack([row, col], axis=1)

    def cell_to_world(self, rc: np.ndarray) -> np.ndarray:
        """(row, col) (N, 2) → cell centres in W (N, 2)."""
        rc = np.atleast_2d(np.asarray(rc, dtype=float))
        return np.stack([self.origin[0] + (rc[:, 1] + 0.5) * self.resolution,
                         self.origin[1] + (rc[:, 0] + 0.5) * self.resolution], axis=1)

    def inside(self, rc: np.ndarray) -> np.ndarray:
        rc = np.atleast_2d(rc)
        return (rc[:, 0] >= 0) & (rc[:, 0] < self.shape[0]) & (rc[:, 1] >= 0) & (rc[:, 1] < self.shape[1])

    def obstacle_distance(self, unknown_is_obstacle: bool = True) -> np.ndarray:
        """Distance [m] from every cell to the nearest occupied (and unknown) cell."""
        blocked = self.cells == OCCUPIED
        if unknown_is_obstacle:
            blocked |= self.cells == UNKNOWN
        free = (~blocked).astype(np.uint8)
        return cv2.distanceTransform(free, cv2.DIST_L2, 5).astype(np.float32) * self.resolution


def load_map(yaml_path: str | Path) -> OccupancyGrid:
    """Read a map_server YAML (image, resolution, origin, negate, occupied_thresh, free_thresh)."""
    yaml_path = Path(yaml_path)
    meta = read_yaml_file(yaml_path, "map file", MapFormatError, str(yaml_path))
    if not isinstance(meta, dict):
        raise MapFormatError(f"{yaml_path}: expected a mapping with image, resolution and origin")
    for key in ("image", "resolution", "origin"):
        if key not in meta:
            raise MapFormatError(f"{yaml_path}: '{key}' is missing")
    res = meta["resolution"]
    if isinstance(res, bool) or not isinstance(res, (int, float)) or not 0 < res < float("inf"):
        raise MapFormatError(f"{yaml_path}: 'resolution' must be a positive number of metres per cell, got {res!r}")
    origin = meta["origin"]
    if not (isinstance(origin, list) and len(origin) == 3 and all(isinstance(v, (int, float)) for v in origin)):
        raise MapFormatError(f"{yaml_path}: 'origin' must be [x, y, yaw], got {origin!r}")
    if abs(origin[2]) > 1e-9:
        raise MapFormatError(f"{yaml_path}: 'origin' yaw must be 0 (rotated maps are not supported)")
    image_path = (yaml_path.parent / str(meta["image"])).resolve()
    img = decode_image_file(image_path, cv2.IMREAD_GRAYSCALE)     # OpenCV's own log line silenced
    if img is None:
        raise MapFormatError(f"{yaml_path}: 'image' {image_path} is not a readable image")
    occ_t, free_t = meta.get("occupied_thresh", 0.65), meta.get("free_thresh", 0.196)
    for key, v in (("occupied_thresh", occ_t), ("free_thresh", free_t)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
            raise MapFormatError(f"{yaml_path}: '{key}' must be a number in [0, 1], got {v!r}")
    p = img.astype(np.float32) / 255.0
    occupancy = p if meta.get("negate", 0) else 1.0 - p
    cells = np.full(img.shape, UNKNOWN, dtype=np.int8)
    cells[occupancy > occ_t] = OCCUPIED
    cells[occupancy < free_t] = FREE
    return OccupancyGrid(np.ascontiguousarray(cells[::-1]), float(res), (float(origin[0]), float(origin[1])))


def save_map(grid: OccupancyGrid, yaml_path: str | Path) -> None:
    """Write ``grid`` as PGM + YAML (map_server conventions, trinary)."""
    yaml_path = Path(yaml_path)
    image = np.full(grid.shape, 205, dtype=np.uint8)
    image[grid.cells == FREE] = 254
    image[grid.cells == OCCUPIED] = 0
    pgm = yaml_path.with_suffix(".pgm")
    cv2.imwrite(str(pgm), image[::-1])
    yaml_path.write_text(yaml.safe_dump({
        "image": pgm.name, "resolution": grid.resolution, "origin": [grid.origin[0], grid.origin[1], 0.0],
        "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196, "mode": "trinary"}, sort_keys=False))


def inflate(grid: OccupancyGrid, radius_m: float) -> OccupancyGrid:
    """A copy where every cell within ``radius_m`` of an obstacle is occupied."""
    dist = grid.obstacle_distance(unknown_is_obstacle=False)
    cells = grid.cells.copy()
    cells[(dist <= radius_m) & (cells != UNKNOWN)] = OCCUPIED
    return OccupancyGrid(cells, grid.resolution, grid.origin)

