"""Navigation-path overlay (paper §IV-C): the planned path drawn on the floor, as augmented reality.

The global path (world frame W, metres, on the floor) is sampled every few centimetres,
transformed into the camera frame with the camera pose, and kept only where the depth image
shows it is not hidden behind something (occluded segments are not drawn) and within
``path_max_distance`` of the walker along the path. The visible runs are projected with K_P and
drawn as lines ``path_width_deg`` wide; the phosphenes they cover go to full level and the
rest are dimmed (:meth:`Overlay.apply`).

Input: ``extras["nav_path"]``, an (N, 2) or (N, 3) array of world points (z = floor height
``path_height`` when only x, y are given), as published on ``/nav/path``.
"""
from __future__ import annotations

import numpy as np

from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.base import Overlay
from raspv_spv.modes.projected_lines import phosphenes_on_lines, visible_in_depth
from raspv_spv.sampling import Sampling


def densify(path: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``step`` metres along a polyline (N, 3) and their distance along it."""
    seg = np.diff(path, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    s = np.arange(0.0, cum[-1] + 1e-9, step)
    if s[-1] < cum[-1]:
        s = np.append(s, cum[-1])
    idx = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    frac = (s - cum[idx]) / np.maximum(seg_len[idx], 1e-12)
    return path[idx] + frac[:, None] * seg[idx], s


class PathOverlay(Overlay):
    name = "path"
    description = "highlight the visible part of the navigation path on the floor"
    needs = frozenset({"camera", "camera_pose", "depth", "nav_path"})
    defaults = {
        "path_width_deg": 2.5,        # drawn line width [deg of visual field]
        "path_max_distance": 6.0,     # draw the path up to this far ahead along it [m]
        "path_height": 0.0,           # world z of the floor when the path has only x, y [m]
        "occlusion_tolerance": 0.15,  # a path point counts as visible up to this behind the depth [m]
    }

    def visible_points(self, inputs: FrameInputs) -> np.ndarray:
        """Path points (M, 3) in the camera frame that the camera sees (not occluded)."""
        path = np.asarray(inputs.extras["nav_path"], dtype=float)
        if path.ndim != 2 or len(path) < 2 or path.shape[1] not in (2, 3):
            return np.empty((0, 3))
        if path.shape[1] == 2:
            path = np.column_stack([path, np.full(len(path), self.settings["path_height"])])
        pts, along = densify(path, 0.05)
        pts = pts[along <= self.settings["path_max_distance"]]
        pose = np.asarray(inputs.camera_pose, dtype=float)
        R, t = pose[:3, :3], pose[:3, 3]
        pc = (pts - t) @ R                        # world → camera: Rᵀ (p − t)
        pc[~visible_in_depth(pc, inputs, self.settings["occlusion_tolerance"])] = np.nan
        return pc                                 # NaN rows split the path into visible runs

    def highlight(self, inputs: FrameInputs, sampling: Sampling) -> np.ndarray:
        key = (self.name, *(self.settings[k] for k in self.defaults))
        points = inputs.cached(key, lambda: self.visible_points(inputs))       # once per frame
        return phosphenes_on_lines(points, sampling, self.settings["path_width_deg"])
