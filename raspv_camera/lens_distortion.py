"""The lens distortion a camera SDK reports, as the OpenCV coefficients a ``CameraInfo`` carries
(``plumb_bob`` k1 k2 p1 p2 k3, or ``rational_polynomial`` k1 k2 p1 p2 k3 k4 k5 k6). No ROS.

RealSense (librealsense ``rs2_intrinsics``): ``brown_conrady`` is OpenCV's model with the same
five coefficients; ``modified_brown_conrady`` and ``inverse_brown_conrady`` (the model of D400
colour streams) are not, and what they mean has changed between SDK versions, so their OpenCV
coefficients are fitted by least squares to the SDK's own projection
(``rs2_project_point_to_pixel``) over the image (:func:`fit_opencv_coefficients`; the residual
is returned so the driver can say when the fit is poor). Fisheye models (``ftheta``, ``kannala_brandt4``) have no OpenCV
pinhole equivalent: :class:`UnsupportedDistortion`.
DepthAI (``ImgTransformation``): the ``Perspective`` model is OpenCV's 14-coefficient one; it is
passed on as 8 (or 5) coefficients when the thin-prism and tilt terms are zero.
"""
from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics

GRID = 24          # fit samples per image side
FIT_TOLERANCE_PX = 0.5


class UnsupportedDistortion(ValueError):
    """A lens model that OpenCV's pinhole coefficients cannot express (the images would need
    rectifying first)."""


def _trimmed(coefficients) -> tuple[float, ...]:
    """() when all zero; 5 coefficients when k4..k6 are zero; else 8."""
    c = [float(v) for v in coefficients] + [0.0] * max(0, 8 - len(coefficients))
    if not any(c):
        return ()
    return tuple(c[:5]) if not any(c[5:8]) else tuple(c[:8])


def _normalised_grid(K: CameraIntrinsics) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.meshgrid(np.linspace(0, K.width - 1, GRID), np.linspace(0, K.height - 1, GRID))
    return (u.ravel() - K.cx) / K.fx, (v.ravel() - K.cy) / K.fy


def fit_opencv_coefficients(undistorted: tuple[np.ndarray, np.ndarray], distorted: tuple[np.ndarray, np.ndarray],
                            K: CameraIntrinsics) -> tuple[tuple[float, ...], float]:
    """(k1 k2 p1 p2 k3, largest residual [px]) taking ``undistorted`` normalised points to
    ``distorted`` ones under OpenCV's model: linear least squares (the model is linear in its
    coefficients)."""
    x, y = undistorted
    xd, yd = distorted
    r2 = x * x + y * y
    ax = np.stack([x * r2, x * r2 ** 2, 2 * x * y, r2 + 2 * x * x, x * r2 ** 3], axis=1)
    ay = np.stack([y * r2, y * r2 ** 2, r2 + 2 * y * y, 2 * x * y, y * r2 ** 3], axis=1)
    A = np.vstack([ax, ay])
    b = np.concatenate([xd - x, yd - y])
    coeffs = np.linalg.lstsq(A, b, rcond=None)[0]
    projected = cv2.projectPoints(np.column_stack([x, y, np.ones_like(x)]), np.zeros(3), np.zeros(3), K.K,
                                  coeffs)[0].reshape(-1, 2)
    target = np.column_stack([xd * K.fx + K.cx, yd * K.fy + K.cy])
    residual = float(np.max(np.linalg.norm(projected - target, axis=1)))
    return tuple(float(v) for v in coeffs), residual


def from_realsense(model: str, coeffs, K: CameraIntrinsics,
                   project: Callable[[np.ndarray], np.ndarray]) -> tuple[tuple[float, ...], float]:
    """(OpenCV coefficients, fit residual [px]; 0 when exact) of librealsense model ``model``
    (an ``rs2_distortion`` name) with its five ``coeffs`` on image ``K``. ``project``: the SDK's
    own projection of (N, 3) camera points to (N, 2) pixels with these intrinsics
    (``rs2_project_point_to_pixel``), which defines the models that are not OpenCV's."""
    c = [float(v) for v in coeffs][:5]
    if model == "none" or not any(c):
        return (), 0.0
    if model in ("ftheta", "kannala_brandt4"):
        raise UnsupportedDistortion(f"lens model {model} (a fisheye model) has no pinhole equivalent")
    if model == "brown_conrady":          # OpenCV's model, the same five coefficients in the same order
        return _trimmed(c), 0.0
    x, y = _normalised_grid(K)
    pixels = np.asarray(project(np.column_stack([x, y, np.ones_like(x)])), dtype=np.float64)
    distorted = ((pixels[:, 0] - K.cx) / K.fx, (pixels[:, 1] - K.cy) / K.fy)
    coefficients, residual = fit_opencv_coefficients((x, y), distorted, K)
    return _trimmed(coefficients), residual


def from_depthai(model: str, coeffs) -> tuple[float, ...]:
    """OpenCV coefficients of a DepthAI ``ImgTransformation``'s model (``CameraModel`` name)
    and its up to 14 coefficients."""
    c = [float(v) for v in coeffs]
    if not any(c):
        return ()
    if model != "Perspective":
        raise UnsupportedDistortion(f"lens model {model} has no pinhole equivalent")
    if any(c[8:]):
        raise UnsupportedDistortion("thin-prism or tilt distortion terms (OpenCV's 14-coefficient model) "
                                    "do not fit a CameraInfo's rational_polynomial")
    return _trimmed(c[:8])
