"""Obstacles as Euclidean clusters of points (no ROS).

Two points belong to the same cluster when a chain of links joins them; a link is
- 3-D proximity: points in voxels whose centroids are within ``tolerance`` (k-d tree on the
  voxel-downsampled cloud, the classic Euclidean cluster extraction), or
- image adjacency: neighbouring samples of the organised cloud closer than the larger of
  ``tolerance`` and ``spacing_factor`` × their spacing on the surface (so far or grazing
  surfaces, whose samples are farther apart than ``tolerance``, still hold together).
Camera frame C, metres.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from raspv_perception.point_cloud import voxel_downsample


def organised_links(indices: np.ndarray, points: np.ndarray, shape: tuple[int, int], tolerance: float,
                    spacing: np.ndarray, spacing_factor: float = 3.0) -> np.ndarray:
    """Links (E, 2) between positions in ``indices`` (flat sample indices of an organised grid of
    ``shape``) that are right/down/diagonal image neighbours closer than
    max(``tolerance``, ``spacing_factor`` × ``spacing`` [m]). ``points`` (len(indices), 3)."""
    h, w = shape
    n = len(indices)
    if n == 0:
        return np.zeros((0, 2), dtype=np.int64)
    # Work on the bounding box of ``indices`` (links only join its samples), with dense grids of
    # the positions, coordinates and spacings (zero off ``indices``; masked below), so each
    # direction is a few whole-grid operations instead of gathers.
    r, c = np.divmod(indices, w)
    r0, c0 = int(r.min()), int(c.min())
    h, w = int(r.max()) + 1 - r0, int(c.max()) + 1 - c0
    cell = (r - r0) * w + (c - c0)
    pos = np.full(h * w, -1, dtype=np.int64)
    pos[cell] = np.arange(n)
    grid = pos.reshape(h, w)
    pts = np.asarray(points)
    xyz = []
    for axis in range(3):
        ch = np.zeros(h * w, dtype=pts.dtype)
        ch[cell] = pts[:, axis]
        xyz.append(ch.reshape(h, w))
    reach = np.zeros(h * w, dtype=np.asarray(spacing).dtype)
    reach[cell] = spacing
    reach = reach.reshape(h, w)
    member = grid >= 0
    out = []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        if dc >= 0:
            sa, sb = (slice(0, h - dr), slice(0, w - dc)), (slice(dr, h), slice(dc, w))
        else:
            sa, sb = (slice(0, h - dr), slice(-dc, w)), (slice(dr, h), slice(0, w + dc))
        dx, dy, dz = (ch[sa] - ch[sb] for ch in xyz)
        dist = np.sqrt((dx * dx + dy * dy) + dz * dz)        # = np.linalg.norm(axis=1), bit for bit
        limit = np.maximum(tolerance, spacing_factor * np.maximum(reach[sa], reach[sb]))
        keep = member[sa] & member[sb] & (dist < limit)
        out.append(np.stack([grid[sa][keep], grid[sb][keep]], axis=1))
    return np.concatenate(out) if out else np.zeros((0, 2), dtype=np.int64)


def euclidean_clusters(points: np.ndarray, voxel_size: float, tolerance: float, min_voxels: int,
                       links: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Cluster id per point (N,) (−1: in a cluster of fewer than ``min_voxels`` occupied voxels)
    and the number of clusters, largest first. ``links`` (E, 2): extra point pairs to join."""
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    n = len(pts)
    if n == 0:
        return np.zeros(0, dtype=np.int64), 0
    grid = voxel_downsample(pts, voxel_size)
    m = len(grid.counts)
    # Sliding-midpoint splits (balanced_tree=False) build faster here; the pairs found are the
    # same set (only their order differs, which the components do not depend on).
    pairs = cKDTree(grid.centroids, balanced_tree=False).query_pairs(tolerance, output_type="ndarray")
    # Graph nodes: voxels 0..m-1; each point is tied to its voxel through the links' endpoints.
    rows = [pairs[:, 0]]
    cols = [pairs[:, 1]]
    if links is not None and len(links):
        rows.append(grid.inverse[links[:, 0]])
        cols.append(grid.inverse[links[:, 1]])
    count, comp = _components(m, np.concatenate(rows), np.concatenate(cols))
    sizes = np.bincount(comp, minlength=count)
    order = np.argsort(-sizes, kind="stable")
    keep = order[sizes[order] >= min_voxels]
    remap = np.full(count, -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    return remap[comp][grid.inverse], len(keep)


def _components(m: int, r: np.ndarray, c: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of the undirected graph on nodes 0..m-1 with edges (r[i], c[i]):
    their number and each node's component, numbered in the order of their smallest node (the
    numbering of ``scipy.sparse.csgraph.connected_components``, without its graph conversions).

    Union-find in whole-array passes: every tree root is hooked to the smallest root it shares
    an edge with (so parent[x] <= x, no cycles), then paths are compressed by pointer jumping,
    until no edge joins two trees."""
    parent = np.arange(m)
    u, v = r, c
    first = True
    while len(u):
        pu, pv = parent[u], parent[v]            # roots: parent is fully compressed here
        if not first:
            joins = pu != pv
            if not joins.any():
                break
            if len(u) > 1024:                    # later passes only need the edges still joining trees
                keep = np.flatnonzero(joins)
                u, v, pu, pv = u[keep], v[keep], pu[keep], pv[keep]
        first = False
        np.minimum.at(parent, np.maximum(pu, pv), np.minimum(pu, pv))
        while True:
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand
    is_root = parent == np.arange(m)
    rank = np.cumsum(is_root) - 1
    return (int(rank[-1]) + 1 if m else 0), rank[parent]
