"""A* on an 8-connected cost grid with the exact static cost-to-go as heuristic (no rclpy).

Graph: cells are nodes; a move to one of the 8 neighbours costs its length (``resolution`` or
``√2·resolution`` m) times the mean cell cost of its two ends; cells of infinite cost are
blocked, and a diagonal move needs both cells it passes between free (no corner cutting).

**Heuristic.** The exact cost-to-go h on the *static* costmap, one scipy Dijkstra from the
goal per goal. The live costmap only adds obstacles, so no live move is cheaper than its static
counterpart, and h is admissible and consistent on it: A* returns optimal paths and expands
only the cells through which a detour costs less than the live obstacles impose.

**Search.** A* with a consistent h is Dijkstra on the *reduced* costs w'(u, v) = w(u, v) −
h(u) + h(v) ≥ 0 (the reduced distance of a cell is f − h(start), A*'s key order up to a
constant). :class:`AStarGrid` keeps the reduced static graph in a scipy CSR matrix, rewrites
only the edges around cells whose live cost differs from the static one, and runs scipy's C
Dijkstra from the start with ``limit``: it settles exactly the cells A* would expand with
f ≤ h(start) + limit and stops there (early exit). The limit starts from the previous search's
detour and doubles until the goal is reached. :func:`astar_reference` is the textbook heapq A*
over the same graph; tests check both give the same costs.
"""
from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

_SQRT2 = math.sqrt(2.0)
_DIRECTIONS = [(0, 1), (1, 0), (0, -1), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1)]


def blocked_border(cell_cost: np.ndarray) -> np.ndarray:
    """A copy of ``cell_cost`` whose outermost ring of cells is blocked (``inf``)."""
    c = np.array(cell_cost, dtype=np.float64)
    c[0, :] = c[-1, :] = c[:, 0] = c[:, -1] = np.inf
    return c


def grid_graph(cell_cost: np.ndarray, resolution: float) -> csr_matrix:
    """The 8-connected move graph of ``cell_cost`` (rows, cols; ``inf`` = blocked) as a CSR
    matrix over flat cell indices (row·cols + col), both directions, weights in cost·metres,
    column indices sorted within each row."""
    rows, cols = cell_cost.shape
    free = np.isfinite(cell_cost)
    idx = np.arange(rows * cols).reshape(rows, cols)
    src_all, dst_all, w_all = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):          # each undirected edge once
        r0, r1 = max(0, -dr), rows - max(0, dr)
        c0, c1 = max(0, -dc), cols - max(0, dc)
        a = (slice(r0, r1), slice(c0, c1))
        b = (slice(r0 + dr, r1 + dr), slice(c0 + dc, c1 + dc))
        ok = free[a] & free[b]
        if dr and dc:   # no corner cutting between two blocked orthogonal neighbours
            ok &= free[r0 + dr:r1 + dr, c0:c1] & free[r0:r1, c0 + dc:c1 + dc]
        step = math.hypot(dr, dc) * resolution
        w = step * 0.5 * (cell_cost[a][ok] + cell_cost[b][ok])
        src, dst = idx[a][ok], idx[b][ok]
        src_all += [src, dst]
        dst_all += [dst, src]
        w_all += [w, w]
    n = rows * cols
    g = csr_matrix((np.concatenate(w_all), (np.concatenate(src_all), np.concatenate(dst_all))), shape=(n, n))
    g.sort_indices()
    return g


@dataclass
class SearchResult:
    chain: list[int] | None      # flat cell indices start → goal, None when there is no path
    cost: float                  # cost of the chain [cost·m] (inf without path)
    expanded: int                # cells settled by the search


class AStarGrid:
    """A* searches on live costs over the static graph of ``static_cost`` (rows, cols, with a
    blocked border: see :func:`blocked_border`)."""

    def __init__(self, static_cost: np.ndarray, resolution: float) -> None:
        self.shape = static_cost.shape
        self.resolution = resolution
        self.static_cost = static_cost
        self.graph = grid_graph(static_cost, resolution)
        g = self.graph
        n = self.shape[0] * self.shape[1]
        self.src = np.repeat(np.arange(n), np.diff(g.indptr))
        self.dst = g.indices.astype(np.int64)
        cols = self.shape[1]
        dr = self.dst // cols - self.src // cols
        dc = self.dst % cols - self.src % cols
        self.step = np.hypot(dr, dc) * resolution
        self.diagonal = (dr != 0) & (dc != 0)
        key = self.src * n + self.dst                            # sorted: rows, then sorted columns
        self.reverse = np.searchsorted(key, self.dst * n + self.src)
        self.goal: int | None = None
        self.h = np.full(n, np.inf)
        self.toward_goal = np.full(n, -9999)
        self._reduced = self.graph.copy()
        self._reduced_static = self.graph.data.copy()
        self._last_detour = 0.0

    def set_goal(self, goal: int) -> None:
        """Heuristic for ``goal`` (flat index): static cost-to-go and the next cell towards it."""
        if goal == self.goal:
            return
        h, pred = dijkstra(self.graph, directed=True, indices=goal, return_predecessors=True)
        self.h, self.toward_goal, self.goal = h, pred, goal
        with np.errstate(invalid="ignore"):
            red = self.graph.data - h[self.src] + h[self.dst]
        red[~np.isfinite(red)] = np.inf
        self._reduced_static = np.maximum(red, 0.0)             # ≥ 0 up to rounding
        self._reduced.data[:] = self._reduced_static
        self._last_detour = 0.0

    def static_chain(self, start: int) -> list[int]:
        """The static optimal chain from ``start`` to the goal (empty if unreachable)."""
        if not math.isfinite(self.h[start]):
            return []
        pred = self.toward_goal
        chain = [start]
        while chain[-1] != self.goal:
            chain.append(int(pred[chain[-1]]))
        return chain

    def _edges_of(self, cells: np.ndarray) -> np.ndarray:
        """Indices of every edge leaving or entering ``cells``."""
        indptr = self.graph.indptr
        starts, ends = indptr[cells], indptr[cells + 1]
        lens = ends - starts
        total = int(lens.sum())
        if total == 0:
            return np.empty(0, np.int64)
        out = np.repeat(starts - np.concatenate([[0], np.cumsum(lens)[:-1]]), lens) + np.arange(total)
        return np.concatenate([out, self.reverse[out]])       # repeats are harmless: same values

    def search(self, live_cost: np.ndarray, start: int, goal: int, changed: np.ndarray) -> SearchResult:
        """A* from ``start`` to ``goal`` on ``live_cost`` (same shape and border as the static
        costs, never lower). ``changed``: flat indices of the cells whose cost differs from the
        static one *and their neighbours* (the edges to rewrite)."""
        if self.goal is None:
            raise RuntimeError("set_goal() first: the heuristic belongs to a goal")
        cols = self.shape[1]
        edges = self._edges_of(changed)
        live = live_cost.ravel()
        reduced = self._reduced
        if len(edges):
            u, v = self.src[edges], self.dst[edges]
            w = self.step[edges] * 0.5 * (live[u] + live[v])
            diag = self.diagonal[edges]
            corner = live[(v // cols) * cols + u % cols] + live[(u // cols) * cols + v % cols]
            w[diag & ~np.isfinite(corner)] = np.inf
            with np.errstate(invalid="ignore"):
                red = w - self.h[u] + self.h[v]
            red[~np.isfinite(red)] = np.inf
            reduced.data[edges] = np.maximum(red, 0.0)
        try:
            offset = self.h[start] - self.h[goal]
            if not math.isfinite(offset):
                return SearchResult(None, math.inf, 0)
            limit = max(0.25, 1.05 * self._last_detour)     # detours change little between replans
            bound = 4.0 * abs(offset) + 50.0
            while True:
                dist, pred = dijkstra(reduced, directed=True, indices=start, return_predecessors=True,
                                      limit=limit if limit < bound else np.inf)
                if math.isfinite(dist[goal]) or limit >= bound:
                    break
                limit *= 2.0
            expanded = int(np.isfinite(dist).sum())
            if not math.isfinite(dist[goal]):
                return SearchResult(None, math.inf, expanded)
            chain = [goal]
            while chain[-1] != start:
                chain.append(int(pred[chain[-1]]))
            chain.reverse()
            self._last_detour = float(dist[goal])
            return SearchResult(chain, float(dist[goal]) + offset, expanded)
        finally:
            if len(edges):
                reduced.data[edges] = self._reduced_static[edges]


def astar_reference(cost: np.ndarray, resolution: float, start: int, goal: int,
                    heuristic: np.ndarray | None = None) -> SearchResult:
    """Textbook A* with a binary heap over the same graph (``cost`` with a blocked border;
    ``heuristic`` defaults to the octile distance, admissible as every cell costs ≥ 1)."""
    rows, cols = cost.shape
    flat = cost.ravel().tolist()
    if heuristic is None:
        r, c = np.divmod(np.arange(rows * cols), cols)
        dy, dx = np.abs(r - goal // cols), np.abs(c - goal % cols)
        heuristic = resolution * (np.maximum(dx, dy) + (_SQRT2 - 1.0) * np.minimum(dx, dy))
    h = np.asarray(heuristic, dtype=float).tolist()
    INF = math.inf
    half, half_diag = 0.5 * resolution, 0.5 * resolution * _SQRT2
    moves = [(dr * cols + dc, half_diag if dr and dc else half, dr * cols if dr and dc else 0, dc if dr and dc else 0)
             for dr, dc in _DIRECTIONS]
    g = {start: 0.0}
    parent = {start: -1}
    heap = [(h[start], 0.0, start)]
    expanded = 0
    while heap:
        _, neg_g, u = heapq.heappop(heap)
        if -neg_g > g[u]:
            continue                                    # a stale entry
        if u == goal:                                   # early exit: the goal is settled
            chain = [u]
            while parent[chain[-1]] >= 0:
                chain.append(parent[chain[-1]])
            return SearchResult(chain[::-1], g[u], expanded)
        expanded += 1
        gu, cu = g[u], flat[u]
        for off, hs, o1, o2 in moves:
            v = u + off
            cv = flat[v]
            if cv == INF or (o1 and (flat[u + o1] == INF or flat[u + o2] == INF)):
                continue
            ng = gu + hs * (cu + cv)
            if ng < g.get(v, INF):
                g[v] = ng
                parent[v] = u
                heapq.heappush(heap, (ng + h[v], -ng, v))
    return SearchResult(None, math.inf, expanded)


def chain_cost(chain, cell_cost: np.ndarray, resolution: float) -> float:
    """Cost of a cell chain (flat indices) under the move model above."""
    c = np.asarray(chain)
    if len(c) < 2:
        return 0.0
    cols = cell_cost.shape[1]
    flat = cell_cost.ravel()
    r, col = np.divmod(c, cols)
    step = np.hypot(np.diff(r), np.diff(col)) * resolution
    return float((step * 0.5 * (flat[c[:-1]] + flat[c[1:]])).sum())
