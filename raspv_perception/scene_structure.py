"""What scene perception reports about one depth frame (no ROS): the core twin of
``raspv_msgs/SceneStructure`` (see ``scene_msg`` for the conversion).

Frames: camera optical frame C (x right, y down, z forward) unless a field says F, the floor
frame (origin on the floor below the camera, y along the floor normal pointing down, z the
viewing direction projected on the floor, x = y × z). Metres, square metres, degrees.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np


class PlaneType(IntEnum):
    """Plane classes, numbered as the constants of ``raspv_msgs/Plane``."""

    FLOOR = 0
    WALL = 1        # vertical and at least ``min_wall_area``
    HORIZONTAL = 2  # facing up, not the floor: tables, seats, steps
    OTHER = 3       # slanted, or vertical but small


class GravitySource(IntEnum):
    """Where the up direction used for classification came from."""

    NONE = 0      # nothing better than "camera y axis points down"
    FLOOR = 1     # the detected floor
    POSE = 2      # the camera pose prior (world z up)
    SUPPORT = 3   # the dominant upward-facing plane (a table top, or a floor outside the first-floor limits)
    IMU = 4       # gravity measured by the camera's accelerometer


@dataclass
class Plane:
    """A planar segment: ``coefficients`` (a, b, c, d) with a·x + b·y + c·z + d = 0, (a, b, c)
    unit and pointing towards the camera (so d > 0 is the camera's distance to the plane);
    ``hull`` (K, 3) convex hull on the plane, ordered; ``height`` of the centroid above the
    floor (NaN without floor); ``num_points`` samples of the processed cloud."""

    type: PlaneType
    coefficients: np.ndarray
    centroid: np.ndarray
    area: float
    height: float
    num_points: int
    hull: np.ndarray

    @property
    def normal(self) -> np.ndarray:
        return self.coefficients[:3]


@dataclass
class ObstacleCluster:
    """A Euclidean cluster of points that are neither floor nor wall, above the floor.

    ``centroid`` in C; ``min_floor``/``max_floor`` corners of its bounding box in F (without a
    floor: in the frame of the support plane, built the same way); ``height`` of its top above
    the floor [m]; ``distance``: horizontal distance from the camera to its nearest point [m].
    """

    centroid: np.ndarray
    min_floor: np.ndarray
    max_floor: np.ndarray
    height: float
    distance: float
    num_points: int


def _nan3() -> np.ndarray:
    return np.full(3, np.nan)


@dataclass
class SceneStructure:
    """Floor, gravity frame, Manhattan axes, planes, obstacles and free floor of one frame.

    ``floor_plane`` (a, b, c, d) in C with the normal pointing up (d = camera height);
    ``camera_to_floor`` 4×4 pose of F in C (C_T_F: maps F coordinates to C); ``camera_pitch_deg``
    positive when looking down; ``camera_roll_deg`` positive when the image's right side is
    lower. ``manhattan_z``/``manhattan_x``: the two horizontal dominant directions of the walls,
    unit, in C; ``manhattan_z`` is the one closest to the viewing direction and
    x = down × z (right-handed like F).
    ``free_floor`` (M, 2): polygon (x, z) in F of obstacle-free floor. ``up`` (3,) the up
    direction in C used to classify planes and where it came from (``gravity_source``).
    """

    floor_found: bool = False
    floor_plane: np.ndarray = field(default_factory=lambda: np.full(4, np.nan))
    camera_to_floor: np.ndarray = field(default_factory=lambda: np.full((4, 4), np.nan))
    camera_height: float = math.nan
    camera_pitch_deg: float = math.nan
    camera_roll_deg: float = math.nan
    manhattan_found: bool = False
    manhattan_x: np.ndarray = field(default_factory=_nan3)
    manhattan_z: np.ndarray = field(default_factory=_nan3)
    planes: list[Plane] = field(default_factory=list)
    obstacles: list[ObstacleCluster] = field(default_factory=list)
    free_floor: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    processing_ms: float = 0.0
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    gravity_source: GravitySource = GravitySource.NONE

    def planes_of(self, kind: PlaneType) -> list[Plane]:
        """The planes of one type, largest first."""
        return sorted((p for p in self.planes if p.type == kind), key=lambda p: -p.area)

    @property
    def floor_to_camera(self) -> np.ndarray:
        """F_T_C (inverse of ``camera_to_floor``), NaN without floor."""
        if not self.floor_found:
            return np.full((4, 4), np.nan)
        T = self.camera_to_floor
        inv = np.eye(4)
        inv[:3, :3] = T[:3, :3].T
        inv[:3, 3] = -T[:3, :3].T @ T[:3, 3]
        return inv
