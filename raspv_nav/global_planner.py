"""Global path planning on the layered costmap (the paper's A* global planner), no rclpy.

:class:`GlobalPlanner` plans world-frame paths (W, metres) with A* (:mod:`raspv_nav.astar`)
over the inflated costs of a :class:`~raspv_nav.costmap.CostmapState`:

1. the goal's exact cost-to-go on the static layer is computed once per goal cell (scipy
   Dijkstra from the goal) and is A*'s heuristic;
2. a start or goal inside the inflated zone (a subject within ``robot_radius`` of a wall or a
   person) is moved to the nearest traversable cell within ``max_relocation``; the path still
   starts at the subject (its first segment leads out of the zone);
3. if the live obstacles leave the static optimal path and its neighbours untouched, that path
   is optimal as it is (live costs are never lower than static ones); otherwise A* searches;
4. the cell chain is shortened where a straight segment stays traversable and no costlier than
   its ends (so the margin from walls is kept), and returned from the subject to the goal.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from raspv_nav.astar import AStarGrid, blocked_border, chain_cost
from raspv_nav.costmap import Costmap, CostmapConfig, CostmapState
from raspv_common.occupancy import OccupancyGrid


class NoPathError(ValueError):
    """Start or goal outside the map or enclosed, or no route between them."""


@dataclass
class PlanResult:
    path: np.ndarray            # (N, 2) W [m], from the subject's position to the goal
    cost: float                 # cost of the cell chain [cost·m]
    start_moved: bool           # the start was inside the inflated zone
    goal_moved: bool            # the goal was inside the inflated zone
    expanded: int               # cells A* settled (0: the static path was reused)


class GlobalPlanner:
    """A* planner over a :class:`Costmap` (static heuristic cached per goal cell)."""

    def __init__(self, costmap: Costmap | OccupancyGrid, config: CostmapConfig | None = None,
                 max_relocation: float = 1.5) -> None:
        self.costmap = costmap if isinstance(costmap, Costmap) else Costmap(costmap, config)
        self.grid = self.costmap.grid
        self.max_relocation = max_relocation
        self._static_cost = blocked_border(self.costmap.static.cell_cost)
        self.search = AStarGrid(self._static_cost, self.grid.resolution)

    # -- cells -----------------------------------------------------------------------------------
    def cell_of(self, xy, what: str) -> tuple[int, int]:
        rc = self.grid.world_to_cell(np.asarray(xy, dtype=float)[:2])[0]
        if not self.grid.inside(rc[None])[0]:
            raise NoPathError(f"{what} {_xy(xy)} is outside the map")
        return int(rc[0]), int(rc[1])

    def nearest_traversable(self, rc: tuple[int, int], cost: np.ndarray) -> tuple[int, int] | None:
        """The traversable cell nearest to ``rc`` within ``max_relocation`` (itself if free)."""
        r, c = rc
        if np.isfinite(cost[r, c]):
            return rc
        k = int(math.ceil(self.max_relocation / self.grid.resolution))
        r0, c0 = max(0, r - k), max(0, c - k)
        rr, cc = np.nonzero(np.isfinite(cost[r0:r + k + 1, c0:c + k + 1]))
        if not len(rr):
            return None
        d2 = (rr + r0 - r) ** 2 + (cc + c0 - c) ** 2
        i = int(np.argmin(d2))
        if d2[i] > k * k:
            return None
        return int(rr[i] + r0), int(cc[i] + c0)

    # -- planning --------------------------------------------------------------------------------
    def plan(self, start_xy, goal_xy, state: CostmapState | None = None) -> PlanResult:
        """Path from ``start_xy`` to ``goal_xy`` (W, m) on ``state`` (default: the costmap's
        current state); raises :class:`NoPathError` with the reason when there is none."""
        state = state if state is not None else self.costmap.state
        cost = blocked_border(state.cell_cost)
        start_xy = np.asarray(start_xy, dtype=float)[:2]
        goal_xy = np.asarray(goal_xy, dtype=float)[:2]
        s_rc, g_rc = self.cell_of(start_xy, "start"), self.cell_of(goal_xy, "goal")
        g_static = self.nearest_traversable(g_rc, self._static_cost)
        if g_static is None:
            raise NoPathError(f"goal {_xy(goal_xy)} is in an obstacle of the building map "
                              f"(no free cell within {self.max_relocation} m)")
        cols = self.grid.shape[1]
        self.search.set_goal(g_static[0] * cols + g_static[1])
        s_free = self.nearest_traversable(s_rc, cost)
        if s_free is None:
            raise NoPathError(f"start {_xy(start_xy)} is enclosed by obstacles "
                              f"(no free cell within {self.max_relocation} m)")
        g_free = self.nearest_traversable(g_rc, cost)
        if g_free is None:
            raise NoPathError(f"goal {_xy(goal_xy)} is blocked by obstacles "
                              f"(no free cell within {self.max_relocation} m)")
        s, g = s_free[0] * cols + s_free[1], g_free[0] * cols + g_free[1]
        h = self.search.h
        if not (math.isfinite(h[s]) and math.isfinite(h[g])):
            raise NoPathError("no path between start and goal on the building map")
        changed = dilate(cost != self._static_cost, 1)      # the cells and their neighbours
        chain, expanded = None, 0
        static_chain = self.search.static_chain(s) if g == self.search.goal else []
        if static_chain and not changed.ravel()[static_chain].any():
            chain = static_chain
        if chain is None:
            result = self.search.search(cost, s, g, np.flatnonzero(changed))
            if result.chain is None:
                raise NoPathError("no path between start and goal: obstacles block every route")
            chain, expanded = result.chain, result.expanded
        cells = np.column_stack(np.divmod(np.asarray(chain), cols))
        keep = self._shortcut(cells, state)
        pts = self.grid.cell_to_world(cells[keep])
        if s_free == s_rc:
            pts[0] = start_xy
        else:
            pts = np.vstack([start_xy, pts])
        if g_free == g_rc:
            pts[-1] = goal_xy
        return PlanResult(pts, chain_cost(chain, cost, self.grid.resolution), s_free != s_rc, g_free != g_rc,
                          expanded)

    # -- smoothing -------------------------------------------------------------------------------
    @staticmethod
    def _line_free(a: np.ndarray, b: np.ndarray, state: CostmapState) -> bool:
        """True when the straight line between cells ``a`` and ``b`` stays traversable and no
        costlier than its ends (samples every half cell)."""
        d = b - a
        t = np.arange(2 * int(max(abs(d[0]), abs(d[1]))) + 1)
        t = t / max(t[-1], 1)
        rr = (a[0] + t * d[0] + 0.5).astype(np.int64)
        cc = (a[1] + t * d[1] + 0.5).astype(np.int64)
        cost = state.cell_cost[rr, cc]
        if not np.all(np.isfinite(cost)):
            return False
        # keep the cost-aware route where it matters: no shortcut through costlier cells
        return bool(cost.max() <= max(cost[0], cost[-1]) + 0.25)

    def _shortcut(self, cells: np.ndarray, state: CostmapState) -> list[int]:
        keep = [0]
        i = 0
        while i < len(cells) - 1:
            j = len(cells) - 1
            while j > i + 1 and not self._line_free(cells[i], cells[j], state):
                j = max(i + 1, (i + j) // 2) if j - i > 8 else j - 1
            keep.append(j)
            i = j
        return keep


def _xy(xy) -> str:
    """A position for messages: "(1.25, 3.00)"."""
    x, y = (float(v) for v in np.asarray(xy, dtype=float)[:2])
    return f"({x:.2f}, {y:.2f})"


def path_length(path: np.ndarray) -> float:
    """Length of a polyline (N, 2) [m]."""
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) > 1 else 0.0


def dilate(mask: np.ndarray, radius_cells: int) -> np.ndarray:
    """``mask`` grown by a disc of ``radius_cells`` (OpenCV)."""
    k = 2 * radius_cells + 1
    return cv2.dilate(mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))).astype(bool)
