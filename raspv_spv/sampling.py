"""Where each phosphene looks in the camera image: P_i^C = K_C·K_P⁻¹·P_i (paper §III-C1), no ROS.

The prosthesis field of view (K_P) and the camera's (K_C, from CameraInfo) are decoupled: the
ray of phosphene i, r_i = K_P⁻¹·P_i, is projected into the camera; a phosphene whose ray leaves
the camera image is *outside* and modes leave it off. Camera pixel coordinates follow
:class:`~raspv_common.intrinsics.CameraIntrinsics` (integer values at pixel centres).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv.phosphene_map import PhospheneMap


@dataclass(frozen=True)
class Sampling:
    """The phosphenes' view of one camera model.

    ``centres`` (N, 2) P_i in phosphene-image px; ``K_P`` 3×3; ``rays`` (N, 3) with z = 1 and
    ``unit_rays`` (N, 3) normalised, both in the camera optical frame; ``uv`` (N, 2) continuous
    camera pixels; ``inside`` (N,) bool; ``rows``/``cols`` (N,) nearest camera pixel (clipped, so
    always valid indices — mask with ``inside``); ``spacing_camera_px``: phosphene spacing δx
    seen in camera pixels (for modes that look at a neighbourhood rather than one pixel).
    """

    camera: CameraIntrinsics
    centres: np.ndarray = field(repr=False)
    K_P: np.ndarray = field(repr=False)
    rays: np.ndarray = field(repr=False)
    unit_rays: np.ndarray = field(repr=False)
    uv: np.ndarray = field(repr=False)
    inside: np.ndarray = field(repr=False)
    rows: np.ndarray = field(repr=False)
    cols: np.ndarray = field(repr=False)
    spacing_camera_px: float = 1.0
    _scaled: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def build(cls, phosphene_map: PhospheneMap, camera: CameraIntrinsics) -> "Sampling":
        rays = phosphene_map.rays()
        unit = rays / np.linalg.norm(rays, axis=1, keepdims=True)
        u, v, _ = camera.project(rays)
        inside = camera.contains(u, v)
        cols = np.clip(np.rint(u), 0, camera.width - 1).astype(np.intp)
        rows = np.clip(np.rint(v), 0, camera.height - 1).astype(np.intp)
        spacing = phosphene_map.spacing_x * camera.fx / phosphene_map.focal_px
        arrays = (rays, unit, np.stack([u, v], axis=1), inside, rows, cols)
        for a in arrays:
            a.flags.writeable = False
        return cls(camera, phosphene_map.centres, phosphene_map.K, *arrays, spacing_camera_px=float(spacing))

    @property
    def count(self) -> int:
        return len(self.centres)

    def for_shape(self, height: int, width: int) -> "Sampling":
        """The same phosphenes seen by this camera resampled to ``width`` × ``height`` px (e.g. a
        depth image at another resolution than the colour image); cached."""
        if (height, width) == (self.camera.height, self.camera.width):
            return self
        key = (height, width)
        if key not in self._scaled:
            scaled = self.camera.scaled(width, height)
            rays = self.rays
            u, v, _ = scaled.project(rays)
            cols = np.clip(np.rint(u), 0, width - 1).astype(np.intp)
            rows = np.clip(np.rint(v), 0, height - 1).astype(np.intp)
            self._scaled[key] = Sampling(scaled, self.centres, self.K_P, rays, self.unit_rays, np.stack([u, v], axis=1),
                                         scaled.contains(u, v), rows, cols,
                                         self.spacing_camera_px * width / self.camera.width)
        return self._scaled[key]

    def sample(self, image: np.ndarray, fill=0) -> np.ndarray:
        """Values of ``image`` (H, W) or (H, W, C) at each phosphene's nearest camera pixel;
        ``fill`` where the ray leaves the image. Images of another size than the camera model
        are treated as the same camera resampled."""
        s = self.for_shape(image.shape[0], image.shape[1])
        values = image[s.rows, s.cols]
        if not s.inside.all():
            values = values.copy()
            values[~s.inside] = fill
        return values
