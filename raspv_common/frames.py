"""Frame names of the graph's tf tree (REP 105, REP 103) and the fixed rotations between them.

::

    map ─► odom ─► base_link ─► head ─► camera_link ─► camera_color_optical_frame
                              (sim)                   (images, camera info, depth, IMU)

- ``map``: world-fixed, z up, gravity-aligned (REP 105). Poses (``/camera/pose``), paths,
  costmaps and world-frame markers use it. Recordings made before tf existed say ``world``:
  every consumer takes it as ``map`` (:func:`is_map_frame`).
- ``odom``: continuous, drifts; ``map → odom`` is the localisation's correction (the slam
  node), identity where the pose does not drift (sim ground truth, the odometry node).
- ``base_link``: the body (sim: the avatar's base on the floor, x forward; a real camera: the
  camera's body unless its mounting is given).
- ``head`` (sim): the neck pivot, turned by ``/head/orientation`` (gaze is in this frame).
- ``camera_link``: the camera body, x forward, y left, z up; ``camera_color_optical_frame``:
  x right, y down, z forward (the camera frame C of every core).
"""
from __future__ import annotations

import numpy as np

MAP = "map"
ODOM = "odom"
BASE_LINK = "base_link"
HEAD = "head"
CAMERA_LINK = "camera_link"
CAMERA_OPTICAL = "camera_color_optical_frame"
LEGACY_WORLD = "world"          # the world frame's name in recordings made before tf

# the optical frame's axes (x right, y down, z forward) in a body frame (x forward, y left, z up)
LINK_FROM_OPTICAL = np.array([[0.0, 0.0, 1.0, 0.0],
                              [-1.0, 0.0, 0.0, 0.0],
                              [0.0, -1.0, 0.0, 0.0],
                              [0.0, 0.0, 0.0, 1.0]])


def is_map_frame(frame_id: str) -> bool:
    """True for the world-fixed frame: ``map``, the legacy ``world`` of older recordings, or ""
    (a message that names no frame)."""
    return frame_id in (MAP, LEGACY_WORLD, "")


def translation(x: float, y: float, z: float) -> np.ndarray:
    """4×4 pure translation [m]."""
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def mounting_transform(xyz, rpy_deg) -> np.ndarray:
    """4×4 parent ← child of a mounting given as x y z [m] and roll pitch yaw [deg] (fixed axes
    x, then y, then z: R = Rz(yaw)·Ry(pitch)·Rx(roll), as URDF and tf2 read them)."""
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", np.radians(np.asarray(rpy_deg, dtype=float))).as_matrix()
    T[:3, 3] = np.asarray(xyz, dtype=float)
    return T


def camera_mounting_edges(optical_frame: str, base_from_camera_link: np.ndarray | None = None
                          ) -> list[tuple[str, str, np.ndarray]]:
    """The fixed transforms of a camera source: ``base_link → camera_link`` (its mounting;
    identity: the camera is the body, hand-held or worn) and ``camera_link → optical_frame``."""
    mounting = np.eye(4) if base_from_camera_link is None else np.asarray(base_from_camera_link, dtype=float)
    return [(BASE_LINK, CAMERA_LINK, mounting), (CAMERA_LINK, optical_frame, LINK_FROM_OPTICAL)]
