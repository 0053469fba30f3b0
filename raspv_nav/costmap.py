"""The layered costmap of the navigation assistant (paper §III-F3), no rclpy.

Two layers on the building map's cells (world frame W, metres):

- the **static layer**: the building map (occupied; unknown counts as occupied unless
  ``unknown_is_obstacle`` is off); it never decays;
- the **obstacle layer** (:mod:`raspv_nav.obstacle_layer`): what the depth camera sees, cleared
  where it sees free space, decaying after its own ``decay_s``.

Their union is *inflated* like a ROS inflation layer: with d the distance from a cell centre to
the nearest obstacle cell (OpenCV's exact Euclidean distance transform),

- d ≤ ``robot_radius``: not traversable (the subject's centre may not go there);
- otherwise the cell cost is 1 + ``cost_weight``·((``inflation_radius`` − d)/(``inflation_radius``
  − ``robot_radius``))², clipped to [1, 1 + ``cost_weight``]: paths keep a margin from walls
  and people when there is room, and squeeze through doors when there is not.

Published as nav_msgs/OccupancyGrid values (:meth:`CostmapState.occupancy_values`): 100 an
obstacle cell, 99 inscribed (not traversable), 1–98 the inflation cost, 0 free, −1 unknown,
so RViz/Foxglove show them with their "costmap" colour scheme.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from raspv_nav.obstacle_layer import ObstacleLayer, ObstacleLayerConfig
from raspv_common.occupancy import OCCUPIED, UNKNOWN, OccupancyGrid


@dataclass(frozen=True)
class CostmapConfig:
    robot_radius: float = 0.30        # [m] cells nearer an obstacle are not traversable
    inflation_radius: float = 1.0     # [m] beyond this the extra cost is zero
    cost_weight: float = 4.0          # extra cost at the robot radius (× step length)
    unknown_is_obstacle: bool = True

    def __post_init__(self) -> None:
        if not 0 < self.robot_radius < self.inflation_radius:
            raise ValueError(f"need 0 < robot_radius < inflation_radius, got {self.robot_radius}, "
                             f"{self.inflation_radius}")
        if self.cost_weight < 0:
            raise ValueError(f"cost_weight must be >= 0, got {self.cost_weight}")


@dataclass
class CostmapState:
    """The inflated costs of one set of obstacle cells (all (rows, cols), W frame grid).

    ``obstacles``: obstacle cells; ``clearance``: distance to the nearest one [m];
    ``traversable``: clearance > robot radius; ``cell_cost``: ≥ 1, ``inf`` where not traversable;
    ``unknown``: cells the building map does not know.
    """

    obstacles: np.ndarray
    clearance: np.ndarray
    traversable: np.ndarray
    cell_cost: np.ndarray
    unknown: np.ndarray
    config: CostmapConfig

    def occupancy_values(self) -> np.ndarray:
        """int8 (rows, cols): 100 obstacle, 99 inscribed, 1–98 inflation cost, 0 free, −1 unknown."""
        c = self.config
        scale = 97.0 / max(c.cost_weight, 1e-9)
        cost = np.where(self.traversable, self.cell_cost, 1.0)
        out = np.where(cost > 1.0, 1.0 + np.floor((cost - 1.0) * scale), 0.0).clip(0, 98).astype(np.int8)
        out[~self.traversable] = 99
        out[self.obstacles] = 100
        out[self.unknown & self.obstacles] = -1
        return out


def distance_to(obstacles: np.ndarray, resolution: float) -> np.ndarray:
    """Distance [m] from each cell centre to the nearest ``obstacles`` cell centre (OpenCV's
    exact Euclidean distance transform)."""
    dist = cv2.distanceTransform((~obstacles).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return dist.astype(np.float64) * resolution


def inflate_obstacles(obstacles: np.ndarray, resolution: float, config: CostmapConfig,
                      unknown: np.ndarray | None = None, clearance: np.ndarray | None = None) -> CostmapState:
    """Inflated costs around ``obstacles`` (bool (rows, cols)) on a grid of ``resolution`` m
    (``clearance``: their distance field when already known)."""
    c = config
    if clearance is None:
        clearance = distance_to(obstacles, resolution)
    traversable = clearance > c.robot_radius
    span = c.inflation_radius - c.robot_radius
    frac = np.clip((c.inflation_radius - clearance) / span, 0.0, 1.0)
    cell_cost = 1.0 + c.cost_weight * frac * frac
    cell_cost[~traversable] = np.inf
    return CostmapState(obstacles, clearance, traversable, cell_cost,
                        np.zeros_like(obstacles) if unknown is None else unknown, c)


class Costmap:
    """Static layer from ``grid`` + live obstacle layer, inflated on :meth:`update`."""

    def __init__(self, grid: OccupancyGrid, config: CostmapConfig | None = None,
                 obstacle_config: ObstacleLayerConfig | None = None) -> None:
        self.grid = grid
        self.config = config or CostmapConfig()
        self.unknown = grid.cells == UNKNOWN
        self.static_obstacles = (grid.cells == OCCUPIED) | (self.unknown if self.config.unknown_is_obstacle else False)
        self.static = inflate_obstacles(self.static_obstacles, grid.resolution, self.config, self.unknown)
        self.obstacle_layer = ObstacleLayer(grid, obstacle_config)
        # camera hits on or next to a known wall are that wall: they add nothing to the map
        k = cv2.getStructuringElement(cv2.MORPH_RECT, (3, 3))
        self._near_static = cv2.dilate(self.static_obstacles.astype(np.uint8), k).astype(bool)
        self.state = self.static
        self._live = np.zeros(grid.shape, bool)

    def live_obstacles(self, now: float | None = None) -> np.ndarray:
        """Obstacle-layer cells that are new to the building map (not on or next to its walls)."""
        return self.obstacle_layer.occupied(now) & ~self._near_static

    def update(self, now: float | None = None) -> CostmapState:
        """Combine the layers as of data time ``now`` [s] (default: the newest observation).

        Only a window around the live cells (their bounding box grown by ``inflation_radius``) is
        re-inflated: the distance field is exact up to ``inflation_radius`` from live obstacles
        and, beyond it, is the static one. Unchanged live cells reuse the last state."""
        live = self.live_obstacles(now)
        if np.array_equal(live, self._live):
            return self.state
        self._live = live
        if not live.any():
            self.state = self.static
            return self.state
        rr, cc = np.nonzero(live)
        m = int(np.ceil(self.config.inflation_radius / self.grid.resolution)) + 1
        r0, r1 = max(0, rr.min() - m), min(self.grid.shape[0], rr.max() + m + 1)
        c0, c1 = max(0, cc.min() - m), min(self.grid.shape[1], cc.max() + m + 1)
        clearance = self.static.clearance.copy()
        window = (slice(r0, r1), slice(c0, c1))
        clearance[window] = np.minimum(clearance[window], distance_to(live[window], self.grid.resolution))
        self.state = inflate_obstacles(self.static_obstacles | live, self.grid.resolution, self.config,
                                       self.unknown, clearance)
        return self.state
