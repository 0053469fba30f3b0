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
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
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
    r, c = np.concatenate(rows), np.concatenate(cols)
    # the links' direction does not matter: weak components of the directed graph are the
    # undirected ones, without symmetrising it first
    graph = csr_matrix((np.ones(len(r), dtype=np.int8), (r, c)), shape=(m, m))
    count, comp = connected_components(graph, directed=True, connection="weak")
    sizes = np.bincount(comp, minlength=count)
    order = np.argsort(-sizes, kind="stable")
    keep = order[sizes[order] >= min_voxels]
    remap = np.full(count, -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    return remap[comp][grid.inverse], len(keep)
