"""Markers of what perception found (no ROS): planes with their hulls, obstacle clusters, the
free floor, a staircase, the planned path.

Scene geometry comes in the camera optical frame C (``SceneStructure``, ``Staircase``), the path
in the world frame W; each builder takes the 4×4 transform from its input's frame to the frame
the markers are published in (W ← C from ``/camera/pose``, or the identity to draw in C).
"""
from __future__ import annotations

import numpy as np

from raspv_perception.scene_structure import PlaneType, SceneStructure
from raspv_perception.stair_model import Staircase
from raspv_viz.shapes import (CUBE, FLOOR, FREE_FLOOR, HORIZONTAL, LINE_LIST, LINE_STRIP, OBSTACLE, OTHER,
                              OUTLINE_WIDTH, PATH, SPHERE, STAIRS, TRIANGLE_LIST, WALL, MarkerShape, closed,
                              fan_triangles, transform_points)

PLANE_COLORS = {PlaneType.FLOOR: FLOOR, PlaneType.WALL: WALL, PlaneType.HORIZONTAL: HORIZONTAL,
                PlaneType.OTHER: OTHER}
FREE_FLOOR_LIFT = 0.01        # m: the free-floor outline is drawn this far above the floor
UNBOXED_OBSTACLE_SIZE = 0.2   # m: an obstacle without a floor frame is a sphere this wide at its centroid
PATH_WIDTH = 0.05             # m


def opaque(color: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    return (color[0], color[1], color[2], 1.0)


def plane_markers(structure: SceneStructure, T: np.ndarray) -> list[MarkerShape]:
    """Each plane's hull filled (triangle fan) and outlined, coloured by its type; namespace
    ``planes/<type>`` (fill) and ``planes/<type>/outline``, id = the plane's index."""
    shapes = []
    for i, plane in enumerate(structure.planes):
        hull = transform_points(T, plane.hull)
        if len(hull) < 3:
            continue
        ns, color = f"planes/{PlaneType(plane.type).name.lower()}", PLANE_COLORS[PlaneType(plane.type)]
        shapes.append(MarkerShape(ns, i, TRIANGLE_LIST, color, (1.0, 1.0, 1.0), points=fan_triangles(hull)))
        shapes.append(MarkerShape(f"{ns}/outline", i, LINE_STRIP, opaque(color), (OUTLINE_WIDTH, 0.0, 0.0),
                                  points=closed(hull)))
    return shapes


def obstacle_markers(structure: SceneStructure, T: np.ndarray) -> list[MarkerShape]:
    """Each obstacle cluster as its bounding box (a cube posed in the floor frame F, whose axes
    the box is aligned with), or, without a floor, a sphere at its centroid; namespace ``obstacles``."""
    shapes = []
    for i, ob in enumerate(structure.obstacles):
        if structure.floor_found:
            lo, hi = np.asarray(ob.min_floor, float), np.asarray(ob.max_floor, float)
            box = np.eye(4)
            box[:3, 3] = (lo + hi) / 2.0
            size = tuple(float(s) for s in np.maximum(hi - lo, 0.01))
            shapes.append(MarkerShape("obstacles", i, CUBE, OBSTACLE, size, pose=T @ structure.camera_to_floor @ box))
        else:
            pose = np.eye(4)
            pose[:3, 3] = transform_points(T, ob.centroid)[0]
            shapes.append(MarkerShape("obstacles", i, SPHERE, OBSTACLE, (UNBOXED_OBSTACLE_SIZE,) * 3, pose=pose))
    return shapes


def free_floor_marker(structure: SceneStructure, T: np.ndarray) -> list[MarkerShape]:
    """The obstacle-free floor polygon (x, z in F) as a closed line just above the floor."""
    poly = np.asarray(structure.free_floor, dtype=np.float64).reshape(-1, 2)
    if not structure.floor_found or len(poly) < 3:
        return []
    in_floor = np.column_stack([poly[:, 0], np.full(len(poly), -FREE_FLOOR_LIFT), poly[:, 1]])   # F: y points down
    points = transform_points(T @ structure.camera_to_floor, in_floor)
    return [MarkerShape("free_floor", 0, LINE_STRIP, FREE_FLOOR, (OUTLINE_WIDTH, 0.0, 0.0), points=closed(points))]


def scene_markers(structure: SceneStructure, T: np.ndarray) -> list[MarkerShape]:
    """Planes, obstacles and free floor of one ``SceneStructure`` (C) in the frame of ``T`` (· ← C)."""
    return plane_markers(structure, T) + obstacle_markers(structure, T) + free_floor_marker(structure, T)


def stair_markers(stair: Staircase | None, T: np.ndarray) -> list[MarkerShape]:
    """The treads filled (``stairs/treads``) and the paper's wireframe — tread outlines and
    risers — as a line list (``stairs/edges``); nothing when no staircase was detected."""
    if stair is None or not stair.steps:
        return []
    treads = np.vstack([fan_triangles(transform_points(T, s.tread_corners)) for s in stair.steps])
    edges = transform_points(T, stair.segments().reshape(-1, 3))
    return [MarkerShape("stairs/treads", 0, TRIANGLE_LIST, STAIRS, (1.0, 1.0, 1.0), points=treads),
            MarkerShape("stairs/edges", 0, LINE_LIST, opaque(STAIRS), (OUTLINE_WIDTH, 0.0, 0.0), points=edges)]


def path_markers(path_world: np.ndarray, T: np.ndarray) -> list[MarkerShape]:
    """The planned path (N, 3) in W as a line (``path``) and its goal as a sphere (``path/goal``);
    ``T``: · ← W. An empty path (no plan) draws nothing."""
    pts = transform_points(T, path_world)
    if len(pts) < 2:
        return []
    goal = np.eye(4)
    goal[:3, 3] = pts[-1]
    return [MarkerShape("path", 0, LINE_STRIP, PATH, (PATH_WIDTH, 0.0, 0.0), points=pts),
            MarkerShape("path/goal", 0, SPHERE, PATH, (0.2, 0.2, 0.2), pose=goal)]
