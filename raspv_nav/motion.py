"""The subject's planar motion, and the map ↔ odometry alignment (no rclpy).

- :func:`planar_pose`: (x, y, yaw) on the floor of a 4×4 pose (yaw of one of its axes);
- :class:`VelocityEstimator`: the measured velocity (v forward, w turning) from successive
  stamped poses, for sources without ``/odom`` (real cameras, replays);
- :class:`MapAlignment`: the building map frame M placed in the odometry/world frame W of the
  poses by a planar transform M ← W given in the graph file (``map_from_odom``: x, y, yaw).
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np


def planar_pose(T: np.ndarray, axis: int = 0) -> tuple[float, float, float]:
    """(x, y, yaw) of pose ``T`` (4×4, W ← frame): position and the heading of the frame's
    ``axis`` column projected on the floor (0: a base's x forward, 2: a camera's optical axis)."""
    d = T[:3, axis]
    return float(T[0, 3]), float(T[1, 3]), math.atan2(float(d[1]), float(d[0]))


def wrap_angle(a):
    """Angle(s) wrapped to (−π, π]."""
    return np.mod(np.asarray(a) + math.pi, 2 * math.pi) - math.pi


class VelocityEstimator:
    """(v, w) from poses (x, y, yaw) stamped in seconds: displacement along the heading and
    yaw change over the last ``window_s`` seconds. A stamp going back clears it."""

    def __init__(self, window_s: float = 0.3) -> None:
        self.window_s = window_s
        self._poses: deque[tuple[float, float, float, float]] = deque()

    def clear(self) -> None:
        self._poses.clear()

    def add(self, stamp: float, x: float, y: float, yaw: float) -> None:
        if self._poses and stamp <= self._poses[-1][0]:
            if stamp < self._poses[-1][0] - 1.0:
                self._poses.clear()                 # a bag looping, a reset
            else:
                return                              # a repeated or slightly late pose
        self._poses.append((stamp, x, y, yaw))
        while len(self._poses) > 2 and stamp - self._poses[1][0] >= self.window_s:
            self._poses.popleft()

    def velocity(self) -> tuple[float, float]:
        """(v [m/s] along the current heading, w [rad/s]); (0, 0) until two poses arrived."""
        if len(self._poses) < 2:
            return 0.0, 0.0
        t0, x0, y0, a0 = self._poses[0]
        t1, x1, y1, a1 = self._poses[-1]
        dt = t1 - t0
        if dt <= 1e-6:
            return 0.0, 0.0
        v = ((x1 - x0) * math.cos(a1) + (y1 - y0) * math.sin(a1)) / dt
        w = float(wrap_angle(a1 - a0)) / dt
        return v, w


def planar_transform(x: float, y: float, yaw: float) -> np.ndarray:
    """4×4 rotation by ``yaw`` [rad] about z and translation (x, y, 0)."""
    c, s = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = x, y
    return T


class MapAlignment:
    """Poses arrive in the world/odometry frame W; the building map lives in its frame M.
    ``map_from_odom`` = (x, y, yaw [rad]) of W's origin and x axis in M."""

    def __init__(self, map_from_odom: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        self.M_W = planar_transform(*map_from_odom)
        self.W_M = np.linalg.inv(self.M_W)
        self.identity = bool(np.allclose(self.M_W, np.eye(4)))

    def pose_to_map(self, T_world: np.ndarray) -> np.ndarray:
        return T_world if self.identity else self.M_W @ T_world

    def points_to_map(self, xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return xy if self.identity else xy @ self.M_W[:2, :2].T + self.M_W[:2, 3]

    def points_to_world(self, xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return xy if self.identity else xy @ self.W_M[:2, :2].T + self.W_M[:2, 3]

    def yaw_to_world(self, yaw: float) -> float:
        return yaw - math.atan2(self.M_W[1, 0], self.M_W[0, 0])
