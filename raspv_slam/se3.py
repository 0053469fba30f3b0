"""Rigid transforms as 4×4 matrices (no ROS): inverse, OpenCV's rvec/tvec, sizes of a motion."""
from __future__ import annotations

import math

import cv2
import numpy as np

from raspv_perception.rgbd_odometry import rotation_angle_deg


def inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform."""
    R, t = T[:3, :3], T[:3, 3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ t
    return out


def from_rvec_tvec(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """OpenCV's (rvec, tvec) — camera ← object — as a 4×4 matrix."""
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))[0]
    T[:3, 3] = np.asarray(tvec, dtype=np.float64).ravel()
    return T


def to_rvec_tvec(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return cv2.Rodrigues(np.ascontiguousarray(T[:3, :3]))[0], np.ascontiguousarray(T[:3, 3]).reshape(3, 1)


def motion_size(T: np.ndarray) -> tuple[float, float]:
    """(translation [m], rotation [deg]) of a motion."""
    return float(np.linalg.norm(T[:3, 3])), rotation_angle_deg(T)


def pose_distance(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(distance between the centres [m], angle between the orientations [deg]) of two poses."""
    return motion_size(inverse(a) @ b)


def viewing_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between the optical axes (z) of two camera poses [deg]."""
    c = float(a[:3, 2] @ b[:3, 2])
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))
