"""The route a virtual patient plans around what it has seen (no rclpy).

A person who sees a box ahead walks around it toward where they are going; they do not turn
at the last moment toward whatever heading happens to be open. :func:`plan_route` gives the
``navigate`` policy that: a shortest path on a grid around the subject built **only from the
obstacles it perceived** (its remembered floor points; unseen space is free, as a person
assumes), inflated by the project's costmap (:func:`raspv_nav.costmap.inflate_obstacles`: not
traversable nearer than the body's radius, a cost that falls to 1 at ``comfort`` m, so the
route keeps a comfortable distance where there is room and squeezes through where there is
not), searched with scipy's Dijkstra on the planner's 8-connected graph
(:func:`raspv_nav.astar.grid_graph`). The goal may lie far outside the grid: every border cell
is a way out, costing its straight-line distance to the goal (a person assumes the unseen part
of the way is open), and so is every cell within ``GOAL_REACH`` of the goal.

Frames: the subject's path-integrated start frame (x ahead at the start, y left), metres.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix, vstack, hstack
from scipy.sparse.csgraph import dijkstra

from raspv_nav.astar import grid_graph
from raspv_nav.costmap import CostmapConfig, inflate_obstacles

RESOLUTION = 0.1        # m per grid cell
HALF_SIZE = 4.0         # m: the grid spans ± this around the subject (beyond its 3 m of sight)
GOAL_REACH = 0.6        # m: cells this near the goal end the route
SWITCH = 0.5            # m: a way round shorter by more than this (a body width) replaces the one taken


@dataclass
class Route:
    points: np.ndarray          # (K, 2) start-frame x, y [m] from the subject's cell toward the goal
    reachable: bool             # False: nothing perceived leaves a way out (points empty)


def plan_route(pose_xy: np.ndarray, goal_xy: np.ndarray, obstacles_xy: np.ndarray, body_radius: float,
               comfort: float, length: float = 2.0, keep: np.ndarray | None = None) -> Route:
    """The first ``length`` m of the cheapest route from ``pose_xy`` to ``goal_xy`` around
    ``obstacles_xy`` (M, 2) for a body of ``body_radius`` that prefers ``comfort`` m of
    clearance (all start frame, metres). ``keep``: the point the subject was heading for; the
    route goes on through it, straight there and cheapest from there, unless that costs more
    than ``SWITCH`` m over the cheapest (a person keeps to the side of an obstacle they chose;
    two nearly equal ways round would otherwise flip from frame to frame)."""
    n = int(round(2 * HALF_SIZE / RESOLUTION)) + 1
    origin = np.asarray(pose_xy, float) - HALF_SIZE                     # centre of cell (0, 0)
    occupied = np.zeros((n, n), bool)
    if len(obstacles_xy):
        ij = np.round((np.asarray(obstacles_xy, float) - origin) / RESOLUTION).astype(int)
        inside = ((ij >= 0) & (ij < n)).all(axis=1)
        occupied[ij[inside, 1], ij[inside, 0]] = True                    # rows: y, cols: x
    config = CostmapConfig(robot_radius=body_radius, inflation_radius=max(comfort, body_radius + RESOLUTION),
                           cost_weight=4.0)
    state = inflate_obstacles(occupied, RESOLUTION, config)
    cost = state.cell_cost
    here = n // 2
    start = here * n + here
    if not np.isfinite(cost[here, here]):            # inside a margin (a bump, a wall too near): leave by the
        free = np.flatnonzero(np.isfinite(cost.ravel()))          # nearest cell the body fits in
        if not len(free):
            return Route(np.empty((0, 2)), False)
        rr, cc = np.divmod(free, n)
        near = np.hypot(rr - here, cc - here) * RESOLUTION
        if near.min() > 2 * comfort:
            return Route(np.empty((0, 2)), False)
        start = int(free[np.argmin(near)])
    cx, cy = origin[0] + RESOLUTION * np.arange(n), origin[1] + RESOLUTION * np.arange(n)
    goal = np.asarray(goal_xy, float)
    # ways out: the border (the unseen rest of the way, assumed open) and the cells within
    # GOAL_REACH of the goal (a goal on an obstacle, e.g. a bin, is reached beside it)
    yy, xx = np.meshgrid(cy, cx, indexing="ij")
    exits = np.hypot(xx - goal[0], yy - goal[1]) <= GOAL_REACH
    exits[0, :] = exits[-1, :] = exits[:, 0] = exits[:, -1] = True
    exits &= np.isfinite(cost)
    if not exits.any():
        return Route(np.empty((0, 2)), False)
    ey, ex = np.nonzero(exits)
    to_goal = np.hypot(cx[ex] - goal[0], cy[ey] - goal[1]) + 1e-6
    g = grid_graph(cost, RESOLUTION)
    # one extra node (index n·n) joined to every exit by its remaining distance: a single-source search
    col = csr_matrix((to_goal, (np.zeros(len(ex), int), ey * n + ex)), shape=(1, n * n))
    graph = vstack([hstack([g, csr_matrix((n * n, 1))]), hstack([col, csr_matrix((1, 1))])]).tocsr()
    dist, pred = dijkstra(graph, directed=False, indices=n * n, return_predecessors=True)
    if not np.isfinite(dist[start]):
        return Route(np.empty((0, 2)), False)
    cells, walked, k = [start], 0.0, start
    if keep is not None:
        kj, ki = np.round((np.asarray(keep, float) - origin) / RESOLUTION).astype(int)
        if 0 <= ki < n and 0 <= kj < n and np.isfinite(dist[ki * n + kj]):
            r0, c0 = divmod(start, n)
            steps = max(abs(ki - r0), abs(kj - c0), 1)
            rr = np.round(np.linspace(r0, ki, steps + 1)).astype(int)
            cc = np.round(np.linspace(c0, kj, steps + 1)).astype(int)
            straight = RESOLUTION * math.hypot(ki - r0, kj - c0)                                   # m
            if np.isfinite(cost[rr, cc]).all() and (straight * float(np.mean(cost[rr, cc]))          # cost·m, as dist
                                                    + dist[ki * n + kj] <= dist[start] + SWITCH):
                cells, walked, k = list(rr * n + cc), straight, ki * n + kj
    while walked < length:
        nxt = int(pred[k])
        if nxt < 0 or nxt == n * n:
            break
        a, b = divmod(k, n), divmod(nxt, n)
        walked += RESOLUTION * math.hypot(a[0] - b[0], a[1] - b[1])
        cells.append(nxt)
        k = nxt
    rr, cc = np.divmod(np.asarray(cells), n)
    return Route(np.column_stack([cx[cc], cy[rr]]), True)
