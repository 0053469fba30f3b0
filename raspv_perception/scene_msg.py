"""``raspv_msgs/SceneStructure`` ↔ :class:`~raspv_perception.scene_structure.SceneStructure`
(no rclpy: message classes only).

The scene node publishes with :func:`structure_to_msg`; consumers (the spv node) turn
``/scene/structure`` back into the core object with :func:`structure_from_msg`. Undefined
floor fields travel as NaN (floats) and an identity pose; ``up`` and ``gravity_source`` travel
as they are (a message without them, all zeros, falls back to the floor's normal or the
defaults).
"""
from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import Point, Vector3
from raspv_msgs.msg import ObstacleCluster as ObstacleClusterMsg
from raspv_msgs.msg import Plane as PlaneMsg
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from std_msgs.msg import Header

from raspv_common.conversions import array_to_point, matrix_to_pose, pose_to_matrix, xyz_to_array
from raspv_perception.scene_structure import (GravitySource, ObstacleCluster, Plane, PlaneType,
                                              SceneStructure)


def _floats(values, n: int) -> list[float]:
    out = [float(v) for v in np.asarray(values, dtype=np.float64).reshape(-1)[:n]]
    return out + [math.nan] * (n - len(out))


def structure_to_msg(s: SceneStructure, header: Header | None = None) -> SceneStructureMsg:
    """Core result → message (``header``: stamp and frame of the depth image)."""
    msg = SceneStructureMsg()
    if header is not None:
        msg.header = header
    msg.floor_found = bool(s.floor_found)
    if s.floor_found:
        msg.floor_plane = _floats(s.floor_plane, 4)
        msg.camera_to_floor = matrix_to_pose(s.camera_to_floor)
        msg.camera_height = float(s.camera_height)
        msg.camera_pitch_deg = float(s.camera_pitch_deg)
        msg.camera_roll_deg = float(s.camera_roll_deg)
    else:
        msg.floor_plane = [math.nan] * 4
        msg.camera_to_floor = matrix_to_pose(np.eye(4))
        msg.camera_height = msg.camera_pitch_deg = msg.camera_roll_deg = math.nan
    msg.manhattan_found = bool(s.manhattan_found)
    mx = s.manhattan_x if s.manhattan_found else np.full(3, np.nan)
    mz = s.manhattan_z if s.manhattan_found else np.full(3, np.nan)
    msg.manhattan_x = Vector3(x=float(mx[0]), y=float(mx[1]), z=float(mx[2]))
    msg.manhattan_z = Vector3(x=float(mz[0]), y=float(mz[1]), z=float(mz[2]))
    for p in s.planes:
        msg.planes.append(PlaneMsg(type=int(p.type), coefficients=_floats(p.coefficients, 4), centroid=array_to_point(p.centroid),
                                   area=float(p.area), height=float(p.height), num_points=int(p.num_points),
                                   hull=[array_to_point(q) for q in np.asarray(p.hull).reshape(-1, 3)]))
    for o in s.obstacles:
        msg.obstacles.append(ObstacleClusterMsg(centroid=array_to_point(o.centroid), min_floor=array_to_point(o.min_floor),
                                                max_floor=array_to_point(o.max_floor), height=float(o.height),
                                                distance=float(o.distance), num_points=int(o.num_points)))
    msg.free_floor = [Point(x=float(x), y=0.0, z=float(z)) for x, z in np.asarray(s.free_floor).reshape(-1, 2)]
    msg.processing_ms = float(s.processing_ms)
    msg.gravity_source = int(s.gravity_source)
    up = np.asarray(s.up, dtype=np.float64)
    msg.up = Vector3(x=float(up[0]), y=float(up[1]), z=float(up[2]))
    return msg


def structure_from_msg(msg: SceneStructureMsg) -> SceneStructure:
    """Message → core object (geometry as float64 arrays)."""
    s = SceneStructure()
    s.floor_found = bool(msg.floor_found)
    if s.floor_found:
        s.floor_plane = np.array(msg.floor_plane, dtype=np.float64)
        s.camera_to_floor = pose_to_matrix(msg.camera_to_floor)
        s.camera_height = float(msg.camera_height)
        s.camera_pitch_deg = float(msg.camera_pitch_deg)
        s.camera_roll_deg = float(msg.camera_roll_deg)
        n = s.floor_plane[:3]
        s.up = n / np.linalg.norm(n)
        s.gravity_source = GravitySource.FLOOR
    s.manhattan_found = bool(msg.manhattan_found)
    if s.manhattan_found:
        s.manhattan_x = xyz_to_array(msg.manhattan_x)
        s.manhattan_z = xyz_to_array(msg.manhattan_z)
    for p in msg.planes:
        hull = np.array([[q.x, q.y, q.z] for q in p.hull], dtype=np.float64).reshape(-1, 3)
        s.planes.append(Plane(PlaneType(p.type), np.array(p.coefficients, dtype=np.float64), xyz_to_array(p.centroid),
                              float(p.area), float(p.height), int(p.num_points), hull))
    for o in msg.obstacles:
        s.obstacles.append(ObstacleCluster(xyz_to_array(o.centroid), xyz_to_array(o.min_floor), xyz_to_array(o.max_floor), float(o.height),
                                           float(o.distance), int(o.num_points)))
    s.free_floor = np.array([[q.x, q.z] for q in msg.free_floor], dtype=np.float64).reshape(-1, 2)
    s.processing_ms = float(msg.processing_ms)
    up = xyz_to_array(msg.up)
    if np.isfinite(up).all() and np.linalg.norm(up) > 0.5:
        s.up = up / np.linalg.norm(up)
        s.gravity_source = GravitySource(int(msg.gravity_source))
    return s
