"""Marker geometry as data (no ROS): what :mod:`raspv_viz.viz_msg` turns into
``visualization_msgs/Marker``. Points are in the frame the markers are published in, metres;
colours RGBA in 0..1.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# Marker kinds, named as visualization_msgs/Marker's type constants.
LINE_STRIP, LINE_LIST, TRIANGLE_LIST, CUBE, SPHERE, SPHERE_LIST = (
    "line_strip", "line_list", "triangle_list", "cube", "sphere", "sphere_list")

# Colours by what a thing is (RGBA): the floor dark blue, walls sand, other horizontal planes
# orange, slanted or small planes grey, obstacles red, free floor and the path green, stairs violet.
FLOOR = (0.20, 0.35, 0.70, 0.55)
WALL = (0.85, 0.75, 0.55, 0.55)
HORIZONTAL = (0.95, 0.55, 0.15, 0.65)
OTHER = (0.60, 0.60, 0.60, 0.45)
OBSTACLE = (0.90, 0.15, 0.15, 0.60)
FREE_FLOOR = (0.10, 0.90, 0.30, 1.00)
STAIRS = (0.75, 0.30, 0.90, 0.60)
PATH = (0.10, 1.00, 0.40, 1.00)
OUTLINE_WIDTH = 0.02   # m


@dataclass
class MarkerShape:
    """One marker. ``points`` (N, 3) for lines, triangles and sphere lists (in the marker's
    frame, ``pose`` applied on top); ``pose`` 4×4 places cubes and spheres (frame ← marker);
    ``scale``: line width in x for lines, size of each axis for cubes, spheres and sphere-list
    elements; ``colors`` (N, 4) per point, or one ``color``."""

    ns: str
    id: int
    kind: str
    color: tuple[float, float, float, float]
    scale: tuple[float, float, float]
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    colors: np.ndarray | None = None


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N, 3) points through the 4×4 transform ``T`` (target ← source)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return p @ T[:3, :3].T + T[:3, 3]


def fan_triangles(polygon: np.ndarray) -> np.ndarray:
    """A convex polygon (K, 3), ordered, as a triangle list (3·(K−2), 3): a fan from its first
    vertex (plane hulls and step treads are convex)."""
    poly = np.asarray(polygon, dtype=np.float64).reshape(-1, 3)
    if len(poly) < 3:
        return np.zeros((0, 3))
    k = len(poly)
    idx = np.stack([np.zeros(k - 2, dtype=int), np.arange(1, k - 1), np.arange(2, k)], axis=1).reshape(-1)
    return poly[idx]


def closed(polyline: np.ndarray) -> np.ndarray:
    """The polygon with its first vertex repeated at the end (a closed line strip)."""
    p = np.asarray(polyline, dtype=np.float64).reshape(-1, 3)
    return np.vstack([p, p[:1]]) if len(p) else p
