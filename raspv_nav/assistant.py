"""The navigation assistant of the paper (§III-F3, §IV-C), no rclpy.

Keeps the building map (global costmap), obstacles recently seen by the depth camera (the
dynamic layer, forgotten after ``memory_s``), replans the global path when asked, and proposes
a collision-free velocity with DWA. Frames: world W (x, y on the floor, z up), metres.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from raspv_nav.global_planner import GlobalPlanner, NoPathError, PlannerConfig
from raspv_nav.local_planner import DWAConfig, DWAPlanner, DWAResult
from raspv_nav.occupancy import OccupancyGrid


@dataclass
class NavigationStatus:
    path: np.ndarray | None          # (N, 2) W, None when no path
    reason: str                      # why there is no path ("" when there is one)
    goal_reached: bool
    distance_to_goal: float          # straight-line [m]
    path_length: float               # [m], nan without path


@dataclass
class NavigationAssistant:
    grid: OccupancyGrid
    goal: np.ndarray
    planner_config: PlannerConfig = field(default_factory=PlannerConfig)
    dwa_config: DWAConfig = field(default_factory=DWAConfig)
    goal_tolerance: float = 0.4      # [m]
    memory_s: float = 2.0            # dynamic obstacles are forgotten after this [s]

    def __post_init__(self) -> None:
        self.goal = np.asarray(self.goal, dtype=float)[:2]
        self.planner = GlobalPlanner(self.grid, self.planner_config)
        self.dwa = DWAPlanner(self.dwa_config)
        self._obstacles: list[tuple[float, np.ndarray]] = []
        self.path: np.ndarray | None = None
        self.reason = "not planned yet"

    def add_obstacles(self, points_xy: np.ndarray, t: float) -> None:
        """Obstacle points (N, 2) in W seen at time ``t`` [s]."""
        self._obstacles.append((t, np.asarray(points_xy, dtype=float).reshape(-1, 2)))

    def recent_obstacles(self, t: float) -> np.ndarray:
        self._obstacles = [(ts, p) for ts, p in self._obstacles if t - ts <= self.memory_s]
        return np.concatenate([p for _, p in self._obstacles]) if self._obstacles else np.empty((0, 2))

    def _dynamic_mask(self, pts: np.ndarray) -> np.ndarray | None:
        if not len(pts):
            return None
        rc = self.grid.world_to_cell(pts)
        rc = rc[self.grid.inside(rc)]
        mask = np.zeros(self.grid.shape, bool)
        mask[rc[:, 0], rc[:, 1]] = True
        return mask

    def replan(self, position: np.ndarray, t: float) -> NavigationStatus:
        """Global path from ``position`` (x, y) to the goal around the map and recent obstacles."""
        position = np.asarray(position, dtype=float)[:2]
        dist = float(np.linalg.norm(self.goal - position))
        if dist <= self.goal_tolerance:
            self.path, self.reason = np.stack([position, self.goal]), ""
            return NavigationStatus(self.path, "", True, dist, dist)
        self.planner.set_dynamic_obstacles(self._dynamic_mask(self.recent_obstacles(t)))
        try:
            self.path, self.reason = self.planner.plan(position, self.goal), ""
        except NoPathError as exc:
            self.path, self.reason = None, str(exc)
        length = float(np.linalg.norm(np.diff(self.path, axis=0), axis=1).sum()) if self.path is not None else float("nan")
        return NavigationStatus(self.path, self.reason, False, dist, length)

    def velocity_hint(self, pose_xy_yaw, velocity, t: float) -> DWAResult:
        """DWA command towards the current path from pose (x, y, yaw) and velocity (v, w)."""
        if self.path is None:
            return DWAResult(0.0, 0.0, np.empty((0, 2)), False)
        if np.linalg.norm(self.goal - np.asarray(pose_xy_yaw[:2])) <= self.goal_tolerance:
            return DWAResult(0.0, 0.0, np.empty((0, 2)), True)
        return self.dwa.command(pose_xy_yaw, velocity, self.path, self.recent_obstacles(t))
