"""A pose for every camera frame between the SLAM core's frames: sparse optical flow from the last
frame the core tracked, then PnP (no ROS).

The SLAM core costs about a 30-Hz frame interval, so on 2 cores the node tracks 10 frames a
second (``max_rate``). A display that predicts the other frames' poses at constant velocity is
degrees off when a hand-held camera speeds up or stops (TUM fr1/rpy with ground-truth poses at
10 Hz and 45 ms late: 1.7° median, 6.7° p95, 14° at most — a floor texture 2 m away slides
25 cm). The frames between are posed here instead, in a few milliseconds: corners of the reference
frame (the last one the core tracked, with its depth) are followed into the new colour image with
pyramidal Lucas–Kanade (OpenCV), and the reference camera ← new camera motion is solved by
``cv2.solvePnPRansac`` from their 3-D points (the lens distortion in the model), refined on the
inliers by Levenberg–Marquardt. The new frame's depth is not needed. A frame the flow cannot place
(too few inliers: a covered camera, a new view) gets no pose; the core's next frame goes on.

Frames: C the camera optical frame (x right, y down, z forward) of the raw (distorted) image;
``ref_from_camera`` = C_ref ← C_new. Pixels of the raw image, depth in metres.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics


@dataclass(frozen=True)
class FlowConfig:
    max_corners: int = 300          # corners followed from the reference (Shi–Tomasi, with depth)
    corner_quality: float = 0.01    # of the strongest corner's score
    corner_spacing_px: float = 12.0  # at least this far apart, so they spread over the image
    scale: float = 0.5              # the flow runs on images this size (half: 4× cheaper, ≈0.1 px at full size)
    window_px: int = 11             # Lucas–Kanade window (pixels of the scaled image)
    pyramid_levels: int = 3         # 2³ · window: follows a turn of ~10° between the reference and the frame
    reprojection_px: float = 2.0    # PnP RANSAC inlier threshold
    min_inliers: int = 30           # fewer: no pose (ORB-SLAM's minimum for tracking)
    min_depth: float = 0.3          # [m] corners with depth in this range only
    max_depth: float = 6.0


@dataclass(frozen=True)
class FlowResult:
    ref_from_camera: np.ndarray | None   # 4×4 C_ref ← C_new, None when the frame could not be placed
    inliers: int
    followed: int                        # corners the flow followed into the frame
    time_ms: float


@dataclass(frozen=True)
class _Reference:
    stamp: float
    grey: np.ndarray                     # (h, w) uint8 at config.scale
    corners: np.ndarray                  # (N, 1, 2) float32 raw pixels
    points: np.ndarray                   # (N, 3) float64 in C_ref [m]


class FlowTracker:
    """Poses of frames relative to a reference frame the SLAM core tracked."""

    def __init__(self, intrinsics: CameraIntrinsics, distortion: tuple[float, ...] = (),
                 config: FlowConfig | None = None) -> None:
        self.intrinsics = intrinsics
        self.config = config or FlowConfig()
        self.K = np.asarray(intrinsics.K, np.float64)
        self.distortion = np.asarray(distortion, np.float64) if distortion else np.zeros(5)
        self.reference: _Reference | None = None

    def set_reference(self, stamp: float, rgb: np.ndarray, depth: np.ndarray) -> int:
        """The frame the core just tracked: colour (H, W, 3) uint8 RGB and depth (H, W) float32
        metres registered to it (NaN: none). Returns how many corners with depth it gives."""
        c = self.config
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        depth = np.asarray(depth, np.float32)
        valid = (np.isfinite(depth) & (depth > c.min_depth) & (depth < c.max_depth)).astype(np.uint8)
        corners = cv2.goodFeaturesToTrack(grey, c.max_corners, c.corner_quality, c.corner_spacing_px, mask=valid)
        if corners is None:
            self.reference = None
            return 0
        corners = corners.astype(np.float32)
        u, v = corners[:, 0, 0], corners[:, 0, 1]
        z = depth[np.clip(np.round(v).astype(int), 0, depth.shape[0] - 1),
                  np.clip(np.round(u).astype(int), 0, depth.shape[1] - 1)].astype(np.float64)
        ok = np.isfinite(z) & (z > c.min_depth) & (z < c.max_depth)
        corners, z = corners[ok], z[ok]
        normalised = cv2.undistortPoints(corners, self.K, self.distortion).reshape(-1, 2)
        points = np.column_stack([normalised * z[:, None], z])
        self.reference = _Reference(float(stamp), self._scaled(grey), corners, points)
        return len(points)

    def _scaled(self, grey: np.ndarray) -> np.ndarray:
        s = self.config.scale
        if s == 1.0:
            return grey
        return cv2.resize(grey, (round(grey.shape[1] * s), round(grey.shape[0] * s)), interpolation=cv2.INTER_AREA)

    def track(self, rgb: np.ndarray, predicted_ref_from_camera: np.ndarray | None = None) -> FlowResult:
        """The motion C_ref ← C of a new colour frame (H, W, 3) uint8 RGB. ``predicted``: a guess
        (e.g. at constant velocity) that starts the flow and the PnP; identity without."""
        t0 = time.perf_counter()
        ref, c = self.reference, self.config
        if ref is None or len(ref.points) < c.min_inliers:
            return FlowResult(None, 0, 0, (time.perf_counter() - t0) * 1e3)
        guess = np.eye(4) if predicted_ref_from_camera is None else np.asarray(predicted_ref_from_camera, np.float64)
        camera_from_ref = np.linalg.inv(guess)
        rvec, _ = cv2.Rodrigues(np.ascontiguousarray(camera_from_ref[:3, :3]))
        tvec = camera_from_ref[:3, 3].reshape(3, 1).copy()
        start, _ = cv2.projectPoints(ref.points, rvec, tvec, self.K, self.distortion)
        start = start.astype(np.float32)
        grey = self._scaled(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))
        moved, status, _ = cv2.calcOpticalFlowPyrLK(
            ref.grey, grey, ref.corners * c.scale, start * c.scale, winSize=(c.window_px, c.window_px),
            maxLevel=c.pyramid_levels, flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01))
        moved = moved / c.scale
        h, w = rgb.shape[:2]
        ok = (status.ravel() == 1) & (moved[:, 0, 0] >= 0) & (moved[:, 0, 0] < w) & \
             (moved[:, 0, 1] >= 0) & (moved[:, 0, 1] < h)
        followed = int(ok.sum())
        if followed < c.min_inliers:
            return FlowResult(None, 0, followed, (time.perf_counter() - t0) * 1e3)
        points, pixels = ref.points[ok], moved[ok].astype(np.float64)
        found, rvec, tvec, inliers = cv2.solvePnPRansac(
            points, pixels, self.K, self.distortion, rvec=rvec.copy(), tvec=tvec.copy(), useExtrinsicGuess=True,
            iterationsCount=100, reprojectionError=c.reprojection_px, confidence=0.99, flags=cv2.SOLVEPNP_ITERATIVE)
        n = 0 if inliers is None else len(inliers)
        if not found or n < c.min_inliers:
            return FlowResult(None, n, followed, (time.perf_counter() - t0) * 1e3)
        idx = inliers.ravel()
        rvec, tvec = cv2.solvePnPRefineLM(points[idx], pixels[idx], self.K, self.distortion, rvec, tvec)
        camera_from_ref = np.eye(4)
        camera_from_ref[:3, :3] = cv2.Rodrigues(rvec)[0]
        camera_from_ref[:3, 3] = tvec.ravel()
        return FlowResult(np.linalg.inv(camera_from_ref), n, followed, (time.perf_counter() - t0) * 1e3)
