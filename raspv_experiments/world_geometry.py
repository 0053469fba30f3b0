"""What the metrics and the report need to know about a world (no rclpy): its occupancy map
(every static object, people excluded), the distance from every cell to the nearest object
(clearance), and the planner's shortest path from a start to a goal region.

Built once per world (a PyBullet world in DIRECT mode with a 16×12 TinyRenderer camera, ≈ 1 s)
and cached for the process.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from raspv_nav.costmap import CostmapConfig
from raspv_nav.global_planner import GlobalPlanner, NoPathError, path_length
from raspv_common.occupancy import OccupancyGrid

MAP_RESOLUTION = 0.05      # m per cell
BODY_RADIUS = 0.25         # m, the avatar's default collision radius (sim body_radius)


@dataclass
class WorldGeometry:
    name: str
    grid: OccupancyGrid                  # every static object (walls, furniture, models, stairs)
    distance: np.ndarray                 # [m] from each cell centre to the nearest occupied cell
    planner: GlobalPlanner               # shortest paths for a body of BODY_RADIUS, no cost margin

    def clearance(self, xy: np.ndarray, body_radius: float = BODY_RADIUS) -> np.ndarray:
        """Distance [m] from the avatar's body (a cylinder of ``body_radius`` at each (x, y)) to
        the nearest static object; negative when overlapping. Measured from the exact point to the
        nearest occupied cell's centre (an object's face lies about half a cell from its
        outermost cells' centres, on either side): within ±3 cm of the true distance to faces
        along the map's axes with the 5 cm map (tests/experiments/test_metrics.py), ±4 cm at corners. Points off the map give NaN."""
        pts = np.asarray(xy, dtype=float).reshape(-1, 2)
        rc = self.grid.world_to_cell(pts)
        inside = self.grid.inside(rc)
        out = np.full(len(pts), np.nan)
        if inside.any():
            d, _ = self._occupied_tree().query(pts[inside])
            out[inside] = d - body_radius
        return out

    def _occupied_tree(self):
        """k-d tree of the occupied cells that border free space (the objects' outlines)."""
        tree = getattr(self, "_tree", None)
        if tree is None:
            from scipy.ndimage import binary_erosion
            from scipy.spatial import cKDTree

            blocked = self.distance <= 0.0
            rows, cols = np.nonzero(blocked & ~binary_erosion(blocked, border_value=1))
            tree = self._tree = cKDTree(self.grid.cell_to_world(np.column_stack([rows, cols])))
        return tree

    def shortest_path(self, start_xy, goal_xy, goal_radius: float) -> tuple[np.ndarray, float]:
        """The planner's shortest path (N, 2) from ``start_xy`` to the goal region and its length
        [m] up to where it enters the region (NaN length when there is none)."""
        goal = np.asarray(goal_xy, float)
        target = self.reachable_point(goal, goal_radius)
        if target is None:
            return np.empty((0, 2)), float("nan")
        try:
            path = self.planner.plan(np.asarray(start_xy, float), target).path
        except NoPathError:
            return np.empty((0, 2)), float("nan")
        return clip_to_region(path, goal, goal_radius)

    def reachable_point(self, goal: np.ndarray, radius: float) -> np.ndarray | None:
        """The goal itself when the body can stand there, else the nearest place within the goal
        region where it can (a goal on an object: "reach the bin"); None when there is none."""
        t = self.planner.costmap.static.traversable
        rc = self.grid.world_to_cell(goal[None])[0]
        if self.grid.inside(rc[None])[0] and t[rc[0], rc[1]]:
            return goal
        rows, cols = np.nonzero(t)
        if not len(rows):
            return None
        centres = self.grid.cell_to_world(np.column_stack([rows, cols]))
        d = np.linalg.norm(centres - goal, axis=1)
        best = int(np.argmin(d))
        return centres[best] if d[best] <= radius else None


def clip_to_region(path: np.ndarray, centre: np.ndarray, radius: float) -> tuple[np.ndarray, float]:
    """``path`` cut where it first comes within ``radius`` of ``centre``; (cut path, its length)."""
    if len(path) == 0:
        return path, float("nan")
    if np.linalg.norm(path[0] - centre) <= radius:
        return path[:1], 0.0
    for i in range(1, len(path)):
        a, b = path[i - 1], path[i]
        if np.linalg.norm(b - centre) <= radius:
            d = b - a
            f = a - centre
            qa, qb, qc = d @ d, 2 * f @ d, f @ f - radius ** 2
            disc = max(qb * qb - 4 * qa * qc, 0.0)
            s = (-qb - np.sqrt(disc)) / (2 * qa) if qa > 0 else 0.0
            cut = np.vstack([path[:i], a + np.clip(s, 0.0, 1.0) * d])
            return cut, path_length(cut)
    return path, path_length(path)


@functools.lru_cache(maxsize=8)
def world_geometry(world: str) -> WorldGeometry:
    """Geometry of ``world`` (a shipped name or a world file path), cached."""
    from raspv_sim.occupancy_export import world_occupancy
    from raspv_sim.simulator import SimConfig, Simulation

    with Simulation(world, SimConfig(width=16, height=12, renderer="tiny")) as sim:
        grid = world_occupancy(sim.world, MAP_RESOLUTION)
        name = sim.spec.name
    planner = GlobalPlanner(grid, CostmapConfig(robot_radius=BODY_RADIUS, cost_weight=0.0))
    return WorldGeometry(name, grid, grid.obstacle_distance(unknown_is_obstacle=True), planner)


@functools.lru_cache(maxsize=4)
def _placement_sim(world: str):
    from raspv_sim.simulator import SimConfig, Simulation

    return Simulation(world, SimConfig(width=16, height=12, renderer="tiny"))


def start_problem(world: str, x: float, y: float, yaw: float) -> str | None:
    """Why the avatar cannot start at (x, y) [m, W] facing ``yaw`` [rad] in ``world`` — the
    simulator's own check (no floor, overlapping an object) — or None."""
    sim = _placement_sim(world)
    sim.avatar.teleport(x, y, yaw)
    return sim.avatar.placement_problem()
