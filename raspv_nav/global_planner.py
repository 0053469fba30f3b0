"""Global path planning on an occupancy grid (the paper's A* global planner), no rclpy.

Shortest paths over the 8-connected grid with scipy's Dijkstra (C implementation), costs
growing near obstacles like a ROS inflation layer, so paths keep a margin from walls. Cells
closer to an obstacle than the robot radius are not traversable. Dynamic obstacles (e.g. from
the depth camera) are passed as extra blocked cells and the graph is rebuilt (vectorised).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from raspv_nav.occupancy import FREE, OccupancyGrid

_NEIGHBOURS = [(0, 1), (1, 0), (1, 1), (1, -1)]  # each undirected edge once; both directions added


class NoPathError(ValueError):
    """Start or goal not traversable, or no route between them."""


@dataclass
class PlannerConfig:
    robot_radius: float = 0.30      # [m] cells nearer an obstacle are not traversable
    inflation_radius: float = 1.0   # [m] beyond this the extra cost is zero
    cost_weight: float = 4.0        # extra cost at the robot radius (× step length)
    unknown_is_obstacle: bool = True


class GlobalPlanner:
    """Plans world-frame paths on ``grid``; ``plan(start, goal)`` returns (N, 2) metres."""

    def __init__(self, grid: OccupancyGrid, config: PlannerConfig | None = None) -> None:
        self.grid = grid
        self.config = config or PlannerConfig()
        self.set_dynamic_obstacles(None)

    def set_dynamic_obstacles(self, blocked: np.ndarray | None) -> None:
        """Extra occupied cells (bool, grid shape), e.g. obstacles seen by the camera."""
        cfg = self.config
        g = self.grid
        occupied = g.cells != FREE if cfg.unknown_is_obstacle else g.cells == 100
        if blocked is not None:
            occupied = occupied | blocked
        dist = cv2.distanceTransform((~occupied).astype(np.uint8), cv2.DIST_L2, 5).astype(np.float32) * g.resolution
        self.traversable = dist > cfg.robot_radius
        span = max(cfg.inflation_radius - cfg.robot_radius, 1e-6)
        extra = cfg.cost_weight * np.clip((cfg.inflation_radius - dist) / span, 0.0, 1.0) ** 2
        self.cell_cost = (1.0 + extra).astype(np.float64)
        self.clearance = dist
        self._graph = self._build_graph()

    def _build_graph(self) -> csr_matrix:
        rows, cols = self.grid.shape
        idx = np.arange(rows * cols).reshape(rows, cols)
        src_all, dst_all, w_all = [], [], []
        for dr, dc in _NEIGHBOURS:
            r0, r1 = max(0, -dr), rows - max(0, dr)
            c0, c1 = max(0, -dc), cols - max(0, dc)
            a = (slice(r0, r1), slice(c0, c1))
            b = (slice(r0 + dr, r1 + dr), slice(c0 + dc, c1 + dc))
            ok = self.traversable[a] & self.traversable[b]
            if dr and dc:  # no corner cutting between two blocked orthogonal neighbours
                ok &= self.traversable[r0 + dr:r1 + dr, c0:c1] & self.traversable[r0:r1, c0 + dc:c1 + dc]
            step = math.hypot(dr, dc) * self.grid.resolution
            w = step * 0.5 * (self.cell_cost[a] + self.cell_cost[b])
            src, dst = idx[a][ok], idx[b][ok]
            src_all += [src, dst]
            dst_all += [dst, src]
            w_all += [w[ok], w[ok]]
        n = rows * cols
        return csr_matrix((np.concatenate(w_all), (np.concatenate(src_all), np.concatenate(dst_all))), shape=(n, n))

    def _cell_index(self, xy, what: str) -> int:
        rc = self.grid.world_to_cell(np.asarray(xy, dtype=float)[:2])[0]
        if not self.grid.inside(rc[None])[0]:
            raise NoPathError(f"{what} {tuple(np.round(xy[:2], 2))} is outside the map")
        if not self.traversable[rc[0], rc[1]]:
            raise NoPathError(f"{what} {tuple(np.round(xy[:2], 2))} is in or too close to an obstacle")
        return int(rc[0] * self.grid.shape[1] + rc[1])

    def plan(self, start_xy, goal_xy) -> np.ndarray:
        """Shortest path from ``start_xy`` to ``goal_xy`` (world, metres) as (N, 2) waypoints,
        start and goal included, shortened where a straight segment stays traversable."""
        s = self._cell_index(start_xy, "start")
        t = self._cell_index(goal_xy, "goal")
        dist, pred = dijkstra(self._graph, directed=True, indices=s, return_predecessors=True)
        if not np.isfinite(dist[t]):
            raise NoPathError("no path between start and goal")
        chain = [t]
        while chain[-1] != s:
            chain.append(int(pred[chain[-1]]))
        cells = np.array([divmod(i, self.grid.shape[1]) for i in chain[::-1]])
        keep = self._shortcut(cells)
        pts = self.grid.cell_to_world(cells[keep])
        pts[0] = np.asarray(start_xy, dtype=float)[:2]
        pts[-1] = np.asarray(goal_xy, dtype=float)[:2]
        return pts

    def _line_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        n = int(max(abs(b - a))) * 2 + 1
        rr = np.round(np.linspace(a[0], b[0], n)).astype(int)
        cc = np.round(np.linspace(a[1], b[1], n)).astype(int)
        if not (self.traversable[rr, cc].all()):
            return False
        # keep the cost-aware route where it matters: no shortcut through high-cost cells
        return bool(self.cell_cost[rr, cc].max() <= max(self.cell_cost[a[0], a[1]], self.cell_cost[b[0], b[1]]) + 0.25)

    def _shortcut(self, cells: np.ndarray) -> list[int]:
        keep = [0]
        i = 0
        while i < len(cells) - 1:
            j = len(cells) - 1
            while j > i + 1 and not self._line_free(cells[i], cells[j]):
                j = max(i + 1, (i + j) // 2) if j - i > 8 else j - 1
            keep.append(j)
            i = j
        return keep


def path_length(path: np.ndarray) -> float:
    """Length of a polyline (N, 2) [m]."""
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) > 1 else 0.0
