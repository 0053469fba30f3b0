"""First-order rolling-shutter correction of a frame by the camera's rotation rate (no ROS).

A rolling-shutter colour camera (Kinect v1, most webcams) exposes row v at
t_mid + (v / H − ½)·readout: turning at ω, each row sees the scene from a camera turned by
ω·τ(v) from the mid-frame one, so a registration with a global-shutter model confuses that skew
with pose (roll follows the yaw rate). With the rotation rate the motion model predicts, rays of
row v are turned into the mid-frame camera: p_mid = exp(ω τ(v)) p_row (rotation only; at a
hand-held walking speed translation moves rays by millimetres over a readout). Keypoints and
their 3-D points are turned exactly; the small colour and depth images are re-sampled (row of
the output taken for the row of the source, first order).

Where the rate comes from (:class:`raspv_slam.slam_system.SlamSystem`): frames at most
``MAX_PREDICTION_INTERVAL_S`` apart (a 30 Hz camera) are corrected before tracking by the motion
model's rate (the last interval's); farther apart (the node's 10 Hz) that rate lags, so the frame
is registered as it is, its own rate is measured from that pose and the two before
(:func:`rotation_rate`: a second-order backward difference, the rate *at* this frame), and its
keypoints are corrected (its images left as seen) and it is registered again when the skew that
rate makes (:func:`skew_px`) is larger than a keypoint's localisation noise.

Frames: C the camera optical frame (x right, y down, z forward); ω in C [rad/s]; readout [s].
"""
from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from raspv_common.intrinsics import CameraIntrinsics


def _rotations(theta: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of rotation vectors (N, 3)."""
    return Rotation.from_rotvec(np.asarray(theta, np.float64).reshape(-1, 3)).as_matrix()


def rotation_rate(stamps, rotations) -> np.ndarray:
    """The rotation rate ω (3,) [rad/s] in the last camera's frame C_k at the last stamp, from the
    last two or three orientations ``rotations`` (W ← C, (3, 3) each) at ``stamps`` [s, increasing].
    Two: the last interval's mean rate (first order; it describes the interval's middle). Three:
    the two intervals' mean rates extrapolated linearly from their middles to the last stamp — the
    second-order backward difference (3ω₁ − ω₀)/2 for equal intervals."""
    if len(stamps) != len(rotations) or len(stamps) not in (2, 3):
        raise ValueError(f"need 2 or 3 stamped orientations, got {len(stamps)} and {len(rotations)}")
    R = [np.asarray(r, np.float64) for r in rotations]
    h1 = stamps[-1] - stamps[-2]
    if not h1 > 0:
        raise ValueError("stamps must increase")
    step = R[-2].T @ R[-1]                                                # C_{k-1} ← C_k
    last = Rotation.from_matrix(step).as_rotvec() / h1                    # axis: same in C_{k-1} and C_k
    if len(stamps) == 2:
        return last
    h0 = stamps[-2] - stamps[-3]
    if not h0 > 0:
        raise ValueError("stamps must increase")
    before = step.T @ (Rotation.from_matrix(R[-3].T @ R[-2]).as_rotvec() / h0)   # into C_k
    return last + (last - before) * h1 / (h1 + h0)


def skew_px(omega: np.ndarray, readout: float, K: CameraIntrinsics) -> float:
    """The largest shift [px] of a pixel between its row's exposure and the mid-row time for a
    camera turning at ``omega`` (3,) [rad/s] in C: half the readout times the image-plane speed
    (pan and tilt at the focal length, roll at the image's half-diagonal), first order."""
    w = np.asarray(omega, np.float64)
    return 0.5 * readout * (max(K.fx, K.fy) * float(np.hypot(w[0], w[1]))
                            + float(np.hypot(K.width, K.height)) / 2 * abs(float(w[2])))


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


def correct_images(rgb: np.ndarray | None, depth: np.ndarray | None, K: CameraIntrinsics, omega: np.ndarray,
                   readout: float) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The small colour and depth images (intrinsics ``K``) re-sampled as the mid-frame camera
    would see them. Depth values are turned too: a point seen at depth d along the row camera's ray
    q (R_vᵀ·r for the mid-frame ray r, z = 1) is at z = d / q_z in the mid-frame camera (a degree of
    turn moves a point 1.5 m to the side by 2.6 cm in depth, several times the Kinect's noise at 2 m).

    Along an output row v the mid-frame ray r = (x(u), y_v, 1) is affine in x(u) = (u − cx)/fx, so
    q = R_vᵀ·r = x(u)·R_v[0] + (y_v·R_v[1] + R_v[2]) (rows of R_v): the maps are outer products,
    not a 3×3 product per pixel."""
    R = row_rotations(np.arange(K.height) + 0.5, K.height, omega, readout)     # per output row
    x = ((np.arange(K.width) - K.cx) / K.fx).astype(np.float32)[None, :]
    y = (np.arange(K.height) - K.cy) / K.fy
    slope = R[:, 0, :].astype(np.float32)                                   # (H, 3): dq/dx of each row
    offset = (y[:, None] * R[:, 1, :] + R[:, 2, :]).astype(np.float32)      # (H, 3): q at x = 0
    inv_z = 1.0 / (offset[:, 2:3] + slope[:, 2:3] * x)
    mx = (offset[:, 0:1] + slope[:, 0:1] * x) * inv_z * np.float32(K.fx) + np.float32(K.cx)
    my = (offset[:, 1:2] + slope[:, 1:2] * x) * inv_z * np.float32(K.fy) + np.float32(K.cy)
    out_rgb = None if rgb is None else cv2.remap(rgb, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    out_depth = None if depth is None else \
        cv2.remap(depth, mx, my, cv2.INTER_NEAREST, borderValue=float("nan")) * inv_z
    return out_rgb, out_depth
