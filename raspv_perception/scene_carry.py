"""A scene-perception result carried into a later depth frame by the camera's motion (no ROS).

Scene perception takes 13 ms per 640×480 frame on a quiet core and two to three times that in a
busy graph, so scene modes that wait for it show each camera frame 40–100 ms late. The spv
node (``carry_scene``) shows every new depth frame at once with the newest result carried into
it, and replaces it with the frame's own result when that arrives:

* :func:`structure_seen_from` moves the geometry (floor plane, planes, obstacles, Manhattan
  axes, up) into the new camera frame C' with ``new_from_old`` = C' ← C (from the camera poses;
  identity without them). The floor frame F is rebuilt below the new camera, as scene
  perception builds it, and what is given in F (free floor, obstacle boxes) follows.
* :func:`carry_labels` labels the new depth frame on scene perception's own sampling grid
  (every ``stride``-th pixel): each pixel's point, from the *new* depth, is projected into the
  old frame and takes the label there; then the new depth is checked against the floor plane
  with scene perception's inlier band (``plane_distance`` + ``plane_distance_quadratic``·z²), so
  floor that something has stepped onto (a walking person, a moved chair) stops being floor at
  once, and floor that comes into view counts as floor. The rest of what came into view (or
  where the old frame had no reading) takes the label of the nearest pixel with a label that is
  not floor: walls and obstacles continue into the new part of the image.

What is not carried: a new obstacle standing on carried floor becomes ``OBSTACLE`` only where its
points rise above the band (its margin on the floor waits for the frame's own result); the
horizontal ``distance`` of obstacles is the old frame's; without a floor, so are the obstacle
boxes and free floor (given in the support plane's frame).
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception import scene_labels as L
from raspv_perception.floor import camera_angles, floor_frame, transform_plane
from raspv_perception.point_cloud import organised_cloud
from raspv_perception.scene_config import SceneConfig
from raspv_perception.scene_structure import ObstacleCluster, SceneStructure

_DEFAULTS = SceneConfig()


def _points(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(…, 3) points mapped by the 4×4 rigid ``T``."""
    return p @ T[:3, :3].T + T[:3, 3]


def structure_seen_from(structure: SceneStructure, new_from_old: np.ndarray) -> SceneStructure:
    """``structure`` of camera frame C expressed in the camera frame C' (``new_from_old`` 4×4,
    C' ← C, metres), with the floor frame rebuilt below the new camera; ``processing_ms`` 0."""
    T = np.asarray(new_from_old, dtype=np.float64)
    R = T[:3, :3]
    out = dataclasses.replace(structure, processing_ms=0.0, up=R @ structure.up,
                              manhattan_x=R @ structure.manhattan_x, manhattan_z=R @ structure.manhattan_z,
                              planes=[dataclasses.replace(p, coefficients=transform_plane(p.coefficients, T),
                                                          centroid=_points(T, p.centroid), hull=_points(T, p.hull))
                                      for p in structure.planes])
    if not structure.floor_found:
        out.obstacles = [dataclasses.replace(o, centroid=_points(T, o.centroid)) for o in structure.obstacles]
        return out
    plane = transform_plane(np.asarray(structure.floor_plane, dtype=np.float64), T)
    out.floor_plane = plane
    out.camera_to_floor = floor_frame(plane)
    out.camera_height = float(plane[3])
    out.camera_pitch_deg, out.camera_roll_deg = camera_angles(plane)
    # F' ← F: the old floor frame as seen from the new one (a turn about the floor normal and a shift)
    fnew_from_fold = np.linalg.inv(out.camera_to_floor) @ T @ np.asarray(structure.camera_to_floor, dtype=np.float64)
    out.free_floor = _floor_xz(fnew_from_fold, np.asarray(structure.free_floor, dtype=np.float64))
    out.obstacles = [_moved_obstacle(o, T, fnew_from_fold) for o in structure.obstacles]
    return out


def _floor_xz(fnew_from_fold: np.ndarray, xz: np.ndarray) -> np.ndarray:
    """(M, 2) floor points (x, z) in F moved to F' (y, along the normal, stays 0)."""
    if len(xz) == 0:
        return xz.reshape(0, 2)
    p = np.column_stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]])
    return _points(fnew_from_fold, p)[:, [0, 2]]


def _moved_obstacle(o: ObstacleCluster, T: np.ndarray, fnew_from_fold: np.ndarray) -> ObstacleCluster:
    """An obstacle in the new camera and floor frames: its F box turned about the floor normal
    (the axis-aligned box of the turned corners)."""
    lo, hi = np.asarray(o.min_floor, dtype=np.float64), np.asarray(o.max_floor, dtype=np.float64)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    moved = _points(fnew_from_fold, corners)
    return dataclasses.replace(o, centroid=_points(T, np.asarray(o.centroid, dtype=np.float64)),
                               min_floor=moved.min(axis=0), max_floor=moved.max(axis=0))


def carry_labels(labels: np.ndarray, depth: np.ndarray, camera: CameraIntrinsics, new_from_old: np.ndarray,
                 floor_plane: np.ndarray | None, stride: int = _DEFAULTS.stride,
                 config: SceneConfig = _DEFAULTS, earlier: Sequence[tuple[np.ndarray, np.ndarray]] = ()) -> np.ndarray:
    """Scene classes (⌈H/stride⌉, ⌈W/stride⌉) uint8 of the new ``depth`` (H, W) [m, NaN = none;
    ``camera`` its intrinsics) from the old frame's ``labels`` (any size, registered to the old
    depth image) and the motion ``new_from_old`` (C' ← C). ``floor_plane``: the floor in the
    *new* camera frame (normal up), or None without floor. ``earlier``: results of frames that
    looked elsewhere (labels, C' ← that frame; the same camera), in order of preference: a pixel
    the old frame did not see takes the label of the first of them that saw it (a head turned
    back to a view seen before gets that view's labels, not ones continued from its neighbours)."""
    cloud = organised_cloud(depth, camera, stride, config.min_depth, config.max_depth)
    valid, p_new = cloud.valid, cloud.points                    # NaN where there is no reading
    out = np.full(valid.shape, L.NONE, np.uint8)
    for source, motion in ((labels, new_from_old), *earlier):
        todo = np.flatnonzero(valid & (out == L.NONE))
        if todo.size == 0:
            break
        old_from_new = np.linalg.inv(np.asarray(motion, dtype=np.float64))
        u, v, _ = camera.project(_points(old_from_new, p_new.reshape(-1, 3)[todo]))
        hl, wl = source.shape
        with np.errstate(invalid="ignore"):
            u = np.rint(u * (wl / camera.width))
            v = np.rint(v * (hl / camera.height))
            seen = (u >= 0) & (u < wl) & (v >= 0) & (v < hl)
        out.reshape(-1)[todo[seen]] = source[v[seen].astype(np.intp), u[seen].astype(np.intp)]
    unknown = valid & (out == L.NONE)           # came into view, or the old frame had no reading there
    floorish = np.zeros(valid.shape, bool)
    if floor_plane is not None and np.all(np.isfinite(floor_plane)):
        z = p_new[..., 2]
        height = p_new @ np.asarray(floor_plane[:3], dtype=np.float32) + np.float32(floor_plane[3])   # above the floor [m]
        band = np.float32(config.plane_distance) + np.float32(config.plane_distance_quadratic) * z * z
        on_floor = valid & (np.abs(height) <= band)
        was_floor = (out == L.FLOOR) | (out == L.FLOOR_BLOCKED)
        left = was_floor & valid & ~on_floor           # floor no more: something stands there now
        out[left] = np.where((height[left] > band[left]) & (height[left] <= config.max_obstacle_height),
                             L.OBSTACLE, L.OTHER)
        out[unknown & on_floor] = L.FLOOR              # floor come into view
        unknown &= ~on_floor
        floorish = (out == L.FLOOR) | (out == L.FLOOR_BLOCKED)
    source = (out != L.NONE) & ~floorish               # what is not floor continues into what is new
    if unknown.any() and source.any():
        _, nearest = cv2.distanceTransformWithLabels((~source).astype(np.uint8), cv2.DIST_L2, 3,
                                                     labelType=cv2.DIST_LABEL_PIXEL)
        by_index = np.zeros(int(source.sum()) + 1, np.uint8)
        by_index[nearest[source]] = out[source]
        out[unknown] = by_index[nearest[unknown]]
    return out
