"""A textured synthetic room (exact depth, colour and poses) for the SLAM tests, rendered small
(320×240) to keep the tests fast."""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import pytest

from raspv_camera.synthetic_scene import SyntheticRoom, camera_rotation
from raspv_common.intrinsics import CameraIntrinsics

K = CameraIntrinsics.from_hfov(320, 240, 60.0)
ROOM = SyntheticRoom(K, texture_cell=0.08)


def pose(x: float, y: float, yaw_deg: float, z: float = 1.6, pitch_down_deg: float = 15.0) -> np.ndarray:
    """W ← C of a camera at (x, y, z) heading ``yaw_deg`` (about world z), pitched down."""
    T = np.eye(4)
    T[:3, :3] = camera_rotation(math.radians(yaw_deg), math.radians(pitch_down_deg))
    T[:3, 3] = (x, y, z)
    return T


@lru_cache(maxsize=256)
def _render(key: tuple) -> tuple[np.ndarray, np.ndarray]:
    return ROOM.render(np.array(key).reshape(4, 4))


def render(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(RGB uint8, depth float32 m) seen from W ← C ``T`` (cached)."""
    return _render(tuple(np.round(np.asarray(T, float).ravel(), 9)))


def motion_error(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(translation [m], rotation [deg]) between two poses or motions."""
    e = np.linalg.inv(a) @ b
    return float(np.linalg.norm(e[:3, 3])), math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(e[:3, :3]) - 1) / 2))))


@pytest.fixture(scope="session")
def room():
    return ROOM
