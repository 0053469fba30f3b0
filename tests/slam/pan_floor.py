"""The floor-point measure of tests/data/tum_fr1_rpy_pan (1.6 s of a real hand-held Kinect v1
turning 53° away and back, at 10 Hz; provenance in its README): where a camera's poses put a
point fixed on the mocap world's floor, where the first camera looks, over the pan."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from raspv_bags.from_frames import read_groundtruth
from raspv_common.pose_buffer import PoseBuffer
from raspv_common.rotations import quaternion_to_matrix

DATA = Path(__file__).resolve().parents[1] / "data" / "tum_fr1_rpy_pan"
FLOOR_TOLERANCE_M = 0.05        # the target for a world-fixed floor texture (5 cm)
PAN_DEG = 30.0                  # the recording turns at least this far away from its first view, and back


def ground_truth(folder: Path = DATA) -> PoseBuffer:
    """World ← camera optical of a TUM recording ``folder`` (default the pan; mocap world: z up,
    the floor at z ≈ 0)."""
    stamps, rows = read_groundtruth(folder / "groundtruth.txt")
    truth = PoseBuffer(max_age_s=1e3, max_extrapolation_s=0.02)
    for t, (x, y, z, qx, qy, qz, qw) in zip(stamps, rows):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = quaternion_to_matrix(qx, qy, qz, qw), (x, y, z)
        truth.add(float(t), T)
    return truth


def turned_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two cameras' optical axes [deg]."""
    return math.degrees(math.acos(np.clip(a[:3, 2] @ b[:3, 2], -1.0, 1.0)))


def floor_point_moved(poses: list[tuple[float, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """(how far [m] the floor point seen by the first camera moved in the poses' map frame at each
    pose, how far [deg] each camera had turned from the first), for ``poses`` (stamp [s],
    map ← camera optical) sorted by stamp."""
    truth = ground_truth()
    first = truth.lookup(poses[0][0])
    origin, axis = first[:3, 3], first[:3, 2]
    point = np.append(origin - origin[2] / axis[2] * axis, 1.0)          # the optical axis meets the floor
    assert 1.0 < np.linalg.norm(point[:3] - origin) < 4.0
    in_map = np.array([(T @ np.linalg.inv(truth.lookup(t)) @ point)[:3] for t, T in poses])
    turned = np.array([turned_deg(first, truth.lookup(t)) for t, _ in poses])
    return np.linalg.norm(in_map - in_map[0], axis=1), turned
