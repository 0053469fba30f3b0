"""Drawing 3-D polylines as augmented reality on the phosphenes (no ROS): shared by the
overlays that project geometry (navigation path, staircase wireframe).

Polylines are (M, 3) points in the camera optical frame C [m]; NaN rows split them into runs.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.sampling import Sampling

MASK_SCALE = 0.25           # the line mask is drawn at a quarter of the phosphene image resolution


def visible_in_depth(pc: np.ndarray, inputs: FrameInputs, tolerance: float) -> np.ndarray:
    """(M,) bool: points of ``pc`` (C) in front of the camera, inside the image and not hidden:
    no more than ``tolerance`` m behind the depth reading at their pixel (no reading: visible)."""
    cam = inputs.camera
    u, v, z = cam.project(pc)
    ok = (z > 0.05) & cam.contains(u, v)
    depth = inputs.depth
    if depth is None:
        return ok
    if depth.shape != (cam.height, cam.width):
        cam = cam.scaled(depth.shape[1], depth.shape[0])
        u, v, _ = cam.project(pc)
        ok &= cam.contains(u, v)
    cols = np.clip(np.rint(np.nan_to_num(u)), 0, depth.shape[1] - 1).astype(np.intp)
    rows = np.clip(np.rint(np.nan_to_num(v)), 0, depth.shape[0] - 1).astype(np.intp)
    d = depth[rows, cols]
    with np.errstate(invalid="ignore"):
        ok &= ~(np.isfinite(d) & (z > d + tolerance))
    return ok


def densify_segments(segments: np.ndarray, step: float) -> np.ndarray:
    """(K, 2, 3) segments → (M, 3) points every ``step`` m along each, NaN rows between them."""
    out = []
    for a, b in np.asarray(segments, dtype=np.float64).reshape(-1, 2, 3):
        n = max(2, int(math.ceil(np.linalg.norm(b - a) / step)) + 1)
        out.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
        out.append(np.full((1, 3), np.nan))
    return np.concatenate(out) if out else np.empty((0, 3))


def phosphenes_on_lines(pc: np.ndarray, sampling: Sampling, width_deg: float) -> np.ndarray:
    """(N,) bool: the phosphenes that lines through the finite runs of ``pc`` (C) cover, drawn
    ``width_deg`` of visual field wide in the phosphene image (projection K_P, after turning
    the points into the displayed view when ``sampling`` is turned)."""
    out = np.zeros(sampling.count, dtype=bool)
    if not np.isfinite(pc).any():
        return out
    if sampling.capture_from_display is not None:      # display-time reprojection: the turned view
        pc = sampling.to_display(pc)
        with np.errstate(invalid="ignore"):
            pc[~(pc[:, 2] > 0.05)] = np.nan             # behind the turned view
    K = sampling.K_P
    with np.errstate(invalid="ignore", divide="ignore"):
        px = np.stack([K[0, 0] * pc[:, 0] / pc[:, 2] + K[0, 2], K[1, 1] * pc[:, 1] / pc[:, 2] + K[1, 2]], axis=1)
    extent = sampling.centres.max(axis=0) + sampling.centres.min(axis=0)   # ≈ image size
    shape = (int(extent[1] * MASK_SCALE) + 2, int(extent[0] * MASK_SCALE) + 2)
    mask = np.zeros(shape, np.uint8)
    width_px = 2.0 * K[0, 0] * math.tan(math.radians(width_deg) / 2.0)
    thickness = max(1, int(round(width_px * MASK_SCALE)))
    finite = np.isfinite(px).all(axis=1)
    # keep far-off projections (points just in front of the camera) inside OpenCV's fixed-point range
    px = np.clip(np.nan_to_num(px), -4 * extent.max(), 5 * extent.max())
    # consecutive finite points form runs; each run is one polyline
    edges = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(np.int8), [0]])))
    runs = [np.round(px[a:b] * MASK_SCALE * 16).astype(np.int32) for a, b in zip(edges[::2], edges[1::2])]
    cv2.polylines(mask, runs, False, 255, thickness, lineType=cv2.LINE_8, shift=4)
    for r in runs:                        # single visible points still mark their phosphene
        if len(r) == 1:
            cv2.circle(mask, tuple(int(x) for x in r[0]), max(1, thickness // 2) * 16, 255, -1, shift=4)
    cx = np.clip(np.rint(sampling.centres[:, 0] * MASK_SCALE).astype(np.intp), 0, shape[1] - 1)
    cy = np.clip(np.rint(sampling.centres[:, 1] * MASK_SCALE).astype(np.intp), 0, shape[0] - 1)
    return mask[cy, cx] > 0
