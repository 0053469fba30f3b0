"""Obstacles as Euclidean clusters of points (no ROS).

Points are grouped into voxels; voxels whose centroids are within ``tolerance`` of each other
are linked (k-d tree), and connected groups are clusters — Euclidean cluster extraction on the
voxel-downsampled cloud, with the cluster id mapped back to every input point.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from raspv_perception.point_cloud import voxel_downsample


def euclidean_clusters(points: np.ndarray, voxel_size: float, tolerance: float, min_voxels: int
                       ) -> tuple[np.ndarray, int]:
    """Cluster id per point (N,) (−1: in a cluster of fewer than ``min_voxels`` voxels) and the
    number of clusters; ids are ordered by cluster size, largest first. Points (N, 3) [m]."""
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    if len(pts) == 0:
        return np.zeros(0, dtype=np.int64), 0
    grid = voxel_downsample(pts, voxel_size)
    m = len(grid.counts)
    pairs = cKDTree(grid.centroids).query_pairs(tolerance, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs), dtype=np.int8), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    count, comp = connected_components(graph, directed=False)
    sizes = np.bincount(comp, minlength=count)
    order = np.argsort(-sizes, kind="stable")
    keep = order[sizes[order] >= min_voxels]
    remap = np.full(count, -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    return remap[comp][grid.inverse], len(keep)
