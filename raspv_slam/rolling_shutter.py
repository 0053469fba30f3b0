"""First-order rolling-shutter correction of a frame by the camera's rotation rate (no ROS).

A rolling-shutter colour camera (Kinect v1, most webcams) exposes row v at
t_mid + (v / H − ½)·readout: turning at ω, each row sees the scene from a camera turned by
ω·τ(v) from the mid-frame one, so a registration with a global-shutter model confuses that skew
with pose (roll follows the yaw rate). With the rotation rate the motion model predicts, rays of
row v are turned into the mid-frame camera: p_mid = exp(ω τ(v)) p_row (rotation only; at a
hand-held walking speed translation moves rays by millimetres over a readout). Keypoints and
their 3-D points are turned exactly; the small colour and depth images are re-sampled (row of
the output taken for the row of the source, first order).

Frames: C the camera optical frame (x right, y down, z forward); ω in C [rad/s]; readout [s].
"""
from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from raspv_common.intrinsics import CameraIntrinsics


def _rotations(theta: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of rotation vectors (N, 3)."""
    return Rotation.from_rotvec(np.asarray(theta, np.float64).reshape(-1, 3)).as_matrix()


def row_rotations(rows: np.ndarray, height: int, omega: np.ndarray, readout: float) -> np.ndarray:
    """C_mid ← C_row rotations (N, 3, 3) of image rows ``rows`` (pixels of an image ``height`` high)."""
    tau = (np.asarray(rows, np.float64) / height - 0.5) * readout
    return _rotations(tau[:, None] * np.asarray(omega, np.float64)[None, :])


def correct_features(uv: np.ndarray, points: np.ndarray, raw_rows: np.ndarray, K: CameraIntrinsics,
                     omega: np.ndarray, readout: float) -> tuple[np.ndarray, np.ndarray]:
    """(keypoints (N, 2), 3-D points (N, 3)) moved into the mid-frame camera; ``raw_rows`` the
    rows the keypoints were exposed at (pixels of the raw image)."""
    R = row_rotations(raw_rows, K.height, omega, readout)
    rays = K.rays(uv[:, 0].astype(np.float64), uv[:, 1].astype(np.float64))
    q = np.einsum("nij,nj->ni", R, rays)
    u, v, _ = K.project(q)
    p = np.einsum("nij,nj->ni", R, np.nan_to_num(points.astype(np.float64)))
    p[~np.isfinite(points[:, 2])] = np.nan
    return np.column_stack([u, v]).astype(np.float32), p.astype(np.float32)


@lru_cache(maxsize=4)
def _ray_grid(K: CameraIntrinsics) -> np.ndarray:
    """Rays (H, W, 3) float32 with z = 1 through every pixel centre."""
    v, u = np.mgrid[0:K.height, 0:K.width].astype(np.float64)
    return K.rays(u.ravel(), v.ravel()).reshape(K.height, K.width, 3).astype(np.float32)


def correct_images(rgb: np.ndarray | None, depth: np.ndarray | None, K: CameraIntrinsics, omega: np.ndarray,
                   readout: float) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The small colour and depth images (intrinsics ``K``) re-sampled as the mid-frame camera
    would see them (depth values kept: a turn of a degree changes them by far less than their noise)."""
    R = row_rotations(np.arange(K.height) + 0.5, K.height, omega, readout).astype(np.float32)   # per output row
    src = np.matmul(_ray_grid(K), R)                                  # rows of rays times R_v: R_vᵀ·ray, mid → row
    inv_z = 1.0 / src[..., 2]
    mx = (K.fx * src[..., 0] * inv_z + K.cx).astype(np.float32)
    my = (K.fy * src[..., 1] * inv_z + K.cy).astype(np.float32)
    out_rgb = None if rgb is None else cv2.remap(rgb, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    out_depth = None if depth is None else cv2.remap(depth, mx, my, cv2.INTER_NEAREST, borderValue=float("nan"))
    return out_rgb, out_depth
