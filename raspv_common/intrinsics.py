"""Pinhole camera model shared by every core (no ROS imports).

Frames: the *camera optical frame* follows ROS REP 103/105 — x right, y down, z forward,
metres. Pixel coordinates (u, v) are continuous with integer values at pixel centres, so a
symmetric camera of width W has cx = (W - 1) / 2 (as the paper's Asus Xtion: 319.5 for 640 px).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# Lens distortion coefficient counts OpenCV's pinhole functions take: k1 k2 p1 p2 [k3 [k4 k5 k6]]
# (ROS: plumb_bob 4-5, rational_polynomial 8).
OPENCV_DISTORTION_COUNTS = (4, 5, 8)


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics of an image of ``width`` × ``height`` px (focal lengths in px)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")
        if not (math.isfinite(self.fx) and math.isfinite(self.fy)) or self.fx <= 0 or self.fy <= 0:
            raise ValueError(f"focal lengths must be finite and positive, got fx={self.fx}, fy={self.fy}")
        if not (math.isfinite(self.cx) and math.isfinite(self.cy)):
            raise ValueError(f"principal point must be finite, got ({self.cx}, {self.cy})")

    @classmethod
    def from_hfov(cls, width: int, height: int, hfov_deg: float) -> "CameraIntrinsics":
        """Square-pixel camera with horizontal field of view ``hfov_deg`` and a centred
        principal point at ((W-1)/2, (H-1)/2)."""
        f = width / (2.0 * math.tan(math.radians(hfov_deg) / 2.0))
        return cls(width, height, f, f, (width - 1) / 2.0, (height - 1) / 2.0)

    def with_margin(self, margin_deg: float) -> "CameraIntrinsics":
        """The same camera (focal lengths, centred principal point) with its image extended by
        ``margin_deg`` of field of view on every side (widths rounded to whole pixels): what a
        renderer draws so that a view turned by up to that much stays inside the image."""
        if not (math.isfinite(margin_deg) and margin_deg >= 0):
            raise ValueError(f"margin must be a non-negative angle, got {margin_deg}")
        m = math.radians(margin_deg)
        half_w = math.atan(self.width / (2.0 * self.fx)) + m
        half_h = math.atan(self.height / (2.0 * self.fy)) + m
        if max(half_w, half_h) >= math.radians(85.0):
            raise ValueError(f"a {margin_deg:g} deg margin makes the field of view "
                             f"{math.degrees(2 * max(half_w, half_h)):.0f} deg; a pinhole image stays below 170 deg")
        width = int(round(2.0 * self.fx * math.tan(half_w)))
        height = int(round(2.0 * self.fy * math.tan(half_h)))
        return CameraIntrinsics(width, height, self.fx, self.fy, (width - 1) / 2.0, (height - 1) / 2.0)

    @classmethod
    def from_matrix(cls, K: np.ndarray, width: int, height: int) -> "CameraIntrinsics":
        K = np.asarray(K, dtype=float).reshape(3, 3)
        return cls(int(width), int(height), float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]))

    @property
    def K(self) -> np.ndarray:
        """3×3 calibration matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def hfov_deg(self) -> float:
        return math.degrees(2.0 * math.atan(self.width / (2.0 * self.fx)))

    @property
    def vfov_deg(self) -> float:
        return math.degrees(2.0 * math.atan(self.height / (2.0 * self.fy)))

    def scaled(self, width: int, height: int) -> "CameraIntrinsics":
        """The same camera resampled to ``width`` × ``height`` px (pixel-centre convention)."""
        sx, sy = width / self.width, height / self.height
        return CameraIntrinsics(width, height, self.fx * sx, self.fy * sy,
                                (self.cx + 0.5) * sx - 0.5, (self.cy + 0.5) * sy - 0.5)

    def rays(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Ray directions (N, 3) in the camera frame with z = 1 through pixels (u, v)."""
        u = np.asarray(u, dtype=float).ravel()
        v = np.asarray(v, dtype=float).ravel()
        return np.stack([(u - self.cx) / self.fx, (v - self.cy) / self.fy, np.ones_like(u)], axis=1)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Project camera-frame points (N, 3) → (u, v, z). Points with z ≤ 0 get NaN pixels."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        z = p[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = np.where(z > 0, 1.0 / z, np.nan)
        return self.fx * p[:, 0] * inv + self.cx, self.fy * p[:, 1] * inv + self.cy, z

    def backproject(self, depth: np.ndarray) -> np.ndarray:
        """Depth image (H, W) in metres → organised point cloud (H, W, 3) in the camera frame.
        Invalid depth (NaN, inf, ≤ 0) gives NaN points."""
        depth = np.asarray(depth, dtype=np.float32)
        if depth.shape != (self.height, self.width):
            raise ValueError(f"depth is {depth.shape[1]}x{depth.shape[0]}, intrinsics are {self.width}x{self.height}")
        z = np.where(np.isfinite(depth) & (depth > 0), depth, np.nan).astype(np.float32)
        u = (np.arange(self.width, dtype=np.float32) - self.cx) / self.fx
        v = (np.arange(self.height, dtype=np.float32) - self.cy) / self.fy
        out = np.empty((self.height, self.width, 3), dtype=np.float32)
        out[..., 0] = z * u[None, :]
        out[..., 1] = z * v[:, None]
        out[..., 2] = z
        return out

    def contains(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """True where continuous pixel coordinates fall inside the image."""
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        return (u >= -0.5) & (u < self.width - 0.5) & (v >= -0.5) & (v < self.height - 0.5)
