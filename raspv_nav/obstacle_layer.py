"""The live obstacle layer of the costmap: obstacles marked from depth, cells seen free cleared, no rclpy.

One depth frame with the camera pose *at its stamp* (W ← C) becomes a :class:`DepthObservation`
on the grid (world frame W, x, y on the floor, z up, floor at z = 0, metres):

- **hits**: the cells under the points between ``min_height`` and ``max_height`` above the
  floor, nearer than ``max_range`` (horizontal distance from the camera);
- **seen free**: the region the camera looked through. Rays are binned by bearing around the
  camera's floor position (``bearing_resolution``); in each bin the free extent is the farthest
  floor or obstacle-band point, capped at the bin's nearest hit (nothing behind a visible
  obstacle is cleared) and at ``max_range`` (a ray reaching past it still proves the first
  ``max_range`` metres free). The star-shaped polygon through the bin extents, around the camera,
  is filled with OpenCV (``cv2.fillPoly``) — the vectorised equivalent of tracing every ray
  with Bresenham as ROS costmaps do. Points above ``max_height`` (ceilings) and below the floor
  by more than ``min_height`` (drops, noise) neither mark nor clear; no-return pixels (NaN)
  clear nothing.

:class:`ObstacleLayer` keeps, per cell, the stamp of its last hit: a cell is an obstacle while
``now − last_hit ≤ decay_s`` (its time constant; ``now`` is the newest *data* stamp, so a
replayed bag decays with bag time). A cell seen free and not hit in a frame is cleared at once:
a person walking by leaves no trail of phantom obstacles. A stamp going back by more than
``reset_on_jump_s`` (a bag looping) clears the layer.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.occupancy import OccupancyGrid

_SHIFT = 4                       # cv2.fillPoly sub-cell precision: coordinates × 2⁴


@dataclass(frozen=True)
class ObstacleLayerConfig:
    min_height: float = 0.10           # [m] lower edge of the obstacle band above the floor
    max_height: float = 1.80           # [m] upper edge (the subject's height)
    max_range: float = 4.0             # [m] horizontal range of marking and clearing
    stride: int = 4                    # use every stride-th pixel in u and v
    bearing_resolution_deg: float = 0.5  # width of the bearing bins of the clearing polygon
    decay_s: float = 10.0              # [s] an obstacle not seen again is forgotten after this
    reset_on_jump_s: float = 1.0       # [s] a stamp this far back clears the layer

    def __post_init__(self) -> None:
        if not 0.0 <= self.min_height < self.max_height:
            raise ValueError(f"obstacle band must satisfy 0 <= min_height < max_height, got "
                             f"{self.min_height}, {self.max_height}")
        if self.max_range <= 0 or self.stride < 1 or self.bearing_resolution_deg <= 0 or self.decay_s < 0:
            raise ValueError("max_range and bearing_resolution_deg must be > 0, stride >= 1, decay_s >= 0")


@dataclass
class DepthObservation:
    """What one depth frame says about the grid: ``hits`` (K,) flat cell indices of obstacle
    points; ``free`` (rows, cols) bool, the cells the camera saw through (hits excluded);
    ``origin`` (x, y) the camera's floor position in W [m]."""

    hits: np.ndarray
    free: np.ndarray
    origin: np.ndarray


def depth_points_world(depth: np.ndarray, intrinsics: CameraIntrinsics, world_from_camera: np.ndarray,
                       stride: int) -> np.ndarray:
    """Valid depth pixels (every ``stride``-th) as world points (N, 3) [m]."""
    d = np.asarray(depth, dtype=np.float32)[::stride, ::stride]
    v, u = np.mgrid[0:depth.shape[0]:stride, 0:depth.shape[1]:stride]
    ok = np.isfinite(d) & (d > 0)
    rays = intrinsics.rays(u[ok], v[ok]) * d[ok][:, None]
    return rays @ world_from_camera[:3, :3].T + world_from_camera[:3, 3]


def observe_depth(depth: np.ndarray, intrinsics: CameraIntrinsics, world_from_camera: np.ndarray,
                  grid: OccupancyGrid, config: ObstacleLayerConfig) -> DepthObservation:
    """Hits and seen-free cells of one depth frame (H, W) [m, NaN = no reading] taken from
    ``world_from_camera`` (4×4 W ← C optical) on ``grid``'s cells."""
    c = config
    T = np.asarray(world_from_camera, dtype=float)
    pts = depth_points_world(depth, intrinsics, T, c.stride)
    origin = T[:2, 3].copy()
    free = np.zeros(grid.shape, bool)
    if not len(pts):
        return DepthObservation(np.empty(0, np.int64), free, origin)
    z = pts[:, 2]
    rel = pts[:, :2] - origin
    rng = np.hypot(rel[:, 0], rel[:, 1])
    forward = T[:2, 2]                                   # the optical axis on the floor
    yaw0 = math.atan2(forward[1], forward[0]) if np.hypot(*forward) > 1e-6 else 0.0
    bearing = np.mod(np.arctan2(rel[:, 1], rel[:, 0]) - yaw0 + math.pi, 2 * math.pi) - math.pi
    band = (z > c.min_height) & (z < c.max_height)
    hit = band & (rng <= c.max_range)
    clearing = (z >= -c.min_height) & (z < c.max_height)

    rc = grid.world_to_cell(pts[hit, :2])
    inside = grid.inside(rc)
    hits = np.unique(rc[inside, 0] * grid.shape[1] + rc[inside, 1])

    # free extent per bearing bin: farthest clearing ray, capped by the nearest hit and the range
    width = math.radians(c.bearing_resolution_deg)
    nbins = int(math.ceil(2 * math.pi / width))
    b = np.clip(((bearing + math.pi) / width).astype(np.int64), 0, nbins - 1)
    nearest_hit = np.full(nbins, np.inf)
    np.minimum.at(nearest_hit, b[band], rng[band])
    extent = np.zeros(nbins)
    np.maximum.at(extent, b[clearing], np.minimum(rng[clearing], c.max_range))
    extent = np.minimum(extent, nearest_hit)
    used = np.nonzero(extent > 0)[0]
    if len(used):
        angles = yaw0 - math.pi + (used + 0.5) * width
        ring = origin + extent[used, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
        poly = ring if len(used) == nbins else np.vstack([origin[None], ring])
        cells = (poly - np.asarray(grid.origin)) / grid.resolution      # (col, row) continuous, cell corners at ints
        pix = np.round((cells - 0.5) * (1 << _SHIFT)).astype(np.int32)  # cv2 samples at cell centres
        mask = np.zeros(grid.shape, np.uint8)
        cv2.fillPoly(mask, [pix.reshape(-1, 1, 2)], 1, lineType=cv2.LINE_8, shift=_SHIFT)
        free = mask.astype(bool)
        free.ravel()[hits] = False
    return DepthObservation(hits, free, origin)


class ObstacleLayer:
    """Obstacles seen by the camera on ``grid``'s cells, with ray-cast clearing and decay."""

    def __init__(self, grid: OccupancyGrid, config: ObstacleLayerConfig | None = None) -> None:
        self.grid = grid
        self.config = config or ObstacleLayerConfig()
        self.last_hit = np.full(grid.shape, -np.inf)      # data stamp [s] of each cell's last hit
        self.observed = np.zeros(grid.shape, bool)         # ever hit or seen free
        self.stamp: float | None = None                    # newest data stamp [s]

    def clear(self) -> None:
        self.last_hit.fill(-np.inf)
        self.observed.fill(False)
        self.stamp = None

    def advance(self, stamp: float) -> None:
        """Move the layer's clock to data time ``stamp`` [s] (a jump back clears it)."""
        if self.stamp is not None and stamp < self.stamp - self.config.reset_on_jump_s:
            self.clear()
        self.stamp = stamp if self.stamp is None else max(self.stamp, stamp)

    def add(self, observation: DepthObservation, stamp: float) -> None:
        """Apply one frame's observation taken at data time ``stamp`` [s]."""
        self.advance(stamp)
        self.last_hit[observation.free] = -np.inf
        self.observed |= observation.free
        flat = self.last_hit.ravel()
        flat[observation.hits] = np.maximum(flat[observation.hits], stamp)
        self.observed.ravel()[observation.hits] = True

    def add_depth(self, depth: np.ndarray, intrinsics: CameraIntrinsics, world_from_camera: np.ndarray,
                  stamp: float) -> DepthObservation:
        obs = observe_depth(depth, intrinsics, world_from_camera, self.grid, self.config)
        self.add(obs, stamp)
        return obs

    def occupied(self, now: float | None = None) -> np.ndarray:
        """(rows, cols) bool: cells hit within ``decay_s`` of ``now`` (default: the newest stamp)."""
        now = self.stamp if now is None else now
        if now is None:
            return np.zeros(self.grid.shape, bool)
        return self.last_hit >= now - self.config.decay_s

    def occupancy_values(self, now: float | None = None) -> np.ndarray:
        """The layer as nav_msgs/OccupancyGrid data (int8): 100 obstacle, 0 seen free, −1 never seen."""
        out = np.where(self.observed, 0, -1).astype(np.int8)
        out[self.occupied(now)] = 100
        return out
