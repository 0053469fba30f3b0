"""The floor: which plane it is (first detection, tracking, pose prior) and the floor frame F
(no ROS).

Planes are (a, b, c, d) in the camera optical frame C with the normal pointing up, towards the
camera, so d is the camera height above the floor. F (paper Fig. 4, docs/DEVELOPING.md):
origin on the floor below the camera, y along the floor normal pointing down, z the camera's
viewing direction projected on the floor, x = y × z.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raspv_perception.plane_fitting import cross3
from raspv_perception.scene_config import SceneConfig

CAMERA_UP = np.array([0.0, -1.0, 0.0])   # "up" in C for an upright camera (y points down)


def floor_frame(plane: np.ndarray) -> np.ndarray:
    """C_T_F (4×4, maps F coordinates to C) of the floor ``plane`` (normal up, d > 0)."""
    n = np.asarray(plane[:3], dtype=np.float64)
    n = n / np.linalg.norm(n)
    d = float(plane[3])
    y = -n
    z = np.array([0.0, 0.0, 1.0]) - y[2] * y
    if np.linalg.norm(z) < 1e-6:            # looking straight down: use the image's up direction
        z = np.array([0.0, -1.0, 0.0]) - y[1] * y
    z /= np.linalg.norm(z)
    x = cross3(y, z)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2] = x, y, z
    T[:3, 3] = -d * n
    return T


def camera_angles(plane: np.ndarray) -> tuple[float, float]:
    """(pitch, roll) [deg] of the camera over the floor ``plane``: pitch > 0 when the optical axis
    points below the horizon, roll > 0 when the image's right side is lower."""
    down = -np.asarray(plane[:3], dtype=np.float64)
    down /= np.linalg.norm(down)
    pitch = math.degrees(math.asin(float(np.clip(down[2], -1.0, 1.0))))
    roll = math.degrees(math.atan2(down[0], down[1]))
    return pitch, roll


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two directions [deg]."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c = float(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b))
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def transform_plane(plane: np.ndarray, b_from_a: np.ndarray) -> np.ndarray:
    """A plane given in frame A expressed in frame B (``b_from_a`` 4×4)."""
    R, t = b_from_a[:3, :3], b_from_a[:3, 3]
    n = R @ plane[:3]
    return np.array([n[0], n[1], n[2], float(plane[3]) - float(n @ t)])


@dataclass
class FloorCandidate:
    """An upward-facing plane: ``plane`` (a, b, c, d) in C and its visible ``area`` [m²]."""

    plane: np.ndarray
    area: float

    @property
    def height(self) -> float:
        return float(self.plane[3])


@dataclass(frozen=True)
class FloorExpectation:
    """Where the floor should be this frame: ``up`` direction in C with a tolerance [deg], and
    either a camera-height range [m] (new floor) or a predicted plane (tracking)."""

    up: np.ndarray
    max_angle_deg: float
    min_height: float
    max_height: float
    predicted: np.ndarray | None = None

    def accepts(self, c: FloorCandidate, min_area: float) -> bool:
        if c.area < min_area or angle_deg(c.plane[:3], self.up) > self.max_angle_deg:
            return False
        return self.min_height <= c.height <= self.max_height


class FloorTracker:
    """Chooses the floor among upward-facing planes, frame after frame.

    First floor: normal within ``first_floor_max_angle_deg`` of the camera's up and camera
    height in [``first_floor_min_height``, ``first_floor_max_height``] (the mounting's limits);
    with a camera pose, normal within ``prior_max_angle_deg`` of the pose's up and the same
    heights; with gravity measured by an IMU, normal within ``prior_max_angle_deg`` of it at any
    height. Among the accepted planes the lowest is the floor (tables, seats and steps stand on
    it), each needing ``min_floor_area`` in view.
    Tracking: the previous floor (moved by the pose change when poses are given) predicts the
    next; a candidate within ``track_max_angle_deg`` and ``track_max_height_change`` is the
    floor (the largest such). After ``track_lost_frames`` frames without it, the search starts
    over — and once, when IMU gravity arrives for a floor that was found without it.
    """

    def __init__(self, config: SceneConfig) -> None:
        self.config = config
        self.reset()

    def reset(self) -> None:
        self._plane_c: np.ndarray | None = None       # last floor in the camera frame of its frame
        self._plane_w: np.ndarray | None = None       # ... and in the world frame when posed
        self._missed = 0
        self._with_gravity = False                    # the tracked floor was first found along IMU gravity
        self._gravity_now = False

    @property
    def tracking(self) -> bool:
        return self._plane_c is not None

    def expectation(self, world_from_camera: np.ndarray | None,
                    gravity_up: np.ndarray | None = None) -> FloorExpectation:
        """The search window for this frame (pose: 4×4 world ← camera, world z up, or None;
        ``gravity_up``: the up direction in C measured by an IMU, or None)."""
        cfg = self.config
        self._gravity_now = gravity_up is not None
        if self._plane_c is not None and self._gravity_now and not self._with_gravity:
            self.reset()              # a floor chosen by the mounting's limits alone: search again along gravity
            self._gravity_now = True
        if self._plane_c is not None:
            if world_from_camera is not None and self._plane_w is not None:
                predicted = transform_plane(self._plane_w, _inverse(world_from_camera))
            else:
                predicted = self._plane_c
            h = float(predicted[3])
            return FloorExpectation(predicted[:3].copy(), cfg.track_max_angle_deg,
                                    h - cfg.track_max_height_change, h + cfg.track_max_height_change, predicted)
        if world_from_camera is not None:
            up = np.asarray(world_from_camera, dtype=np.float64)[:3, :3].T @ np.array([0.0, 0.0, 1.0])
            return FloorExpectation(up, cfg.prior_max_angle_deg, cfg.first_floor_min_height, cfg.first_floor_max_height)
        if gravity_up is not None:
            up = np.asarray(gravity_up, dtype=np.float64)
            return FloorExpectation(up / np.linalg.norm(up), cfg.prior_max_angle_deg, 0.0, cfg.max_depth)
        return FloorExpectation(CAMERA_UP.copy(), cfg.first_floor_max_angle_deg,
                                cfg.first_floor_min_height, cfg.first_floor_max_height)

    def choose(self, candidates: list[FloorCandidate], expectation: FloorExpectation) -> FloorCandidate | None:
        """The floor among ``candidates``, or None: a new floor is the lowest accepted plane
        with ``min_floor_area`` in view, a tracked floor the largest accepted plane with
        ``track_min_floor_area``."""
        if expectation.predicted is not None:
            ok = [c for c in candidates if expectation.accepts(c, self.config.track_min_floor_area)]
            return max(ok, key=lambda c: c.area) if ok else None
        ok = [c for c in candidates if expectation.accepts(c, self.config.min_floor_area)]
        return max(ok, key=lambda c: c.height) if ok else None

    def update(self, floor: np.ndarray | None, world_from_camera: np.ndarray | None) -> None:
        """Record this frame's floor plane in C (or None when not seen)."""
        if floor is None:
            if self._plane_c is not None:
                self._missed += 1
                if self._missed >= self.config.track_lost_frames:
                    self.reset()
            return
        if self._plane_c is None:
            self._with_gravity = self._gravity_now
        self._missed = 0
        self._plane_c = np.asarray(floor, dtype=np.float64).copy()
        self._plane_w = (transform_plane(self._plane_c, np.asarray(world_from_camera, dtype=np.float64))
                         if world_from_camera is not None else None)


def _inverse(T: np.ndarray) -> np.ndarray:
    T = np.asarray(T, dtype=np.float64)
    inv = np.eye(4)
    inv[:3, :3] = T[:3, :3].T
    inv[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return inv
