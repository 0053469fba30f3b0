"""A keyframe: the features, 3-D points and a compact copy of the images of one frame the map
keeps (no ROS).

The images are kept compressed at the dense-registration size (colour JPEG, depth 16-bit PNG
in 0.2 mm units, as TUM stores depth): ≈ 60 KB a keyframe instead of ≈ 1.2 MB of registration
tensors, so a 10-minute walk stays far below a gigabyte. Keyframes decoded for registration
are cached by the map (a few recent ones).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from raspv_slam.features import Features

DEPTH_UNITS_PER_METRE = 5000.0      # 16-bit PNG depth, TUM's scale (0.2 mm, up to 13.1 m)
JPEG_QUALITY = 90


def encode_images(small_rgb: np.ndarray | None, small_depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(JPEG bytes of the colour (empty without colour), PNG bytes of the depth) as uint8 arrays."""
    color = np.zeros(0, np.uint8)
    if small_rgb is not None:
        ok, buf = cv2.imencode(".jpg", cv2.cvtColor(small_rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        color = buf.ravel() if ok else color
    d = np.nan_to_num(small_depth, nan=0.0) * DEPTH_UNITS_PER_METRE
    ok, buf = cv2.imencode(".png", np.clip(np.rint(d), 0, 65535).astype(np.uint16))
    if not ok:
        raise ValueError("cannot encode a keyframe's depth image")
    return color, buf.ravel()


def decode_images(color: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """The inverse of :func:`encode_images`: (RGB uint8 or None, depth float32 metres with NaN)."""
    rgb = None
    if len(color):
        bgr = cv2.imdecode(color, cv2.IMREAD_COLOR)
        rgb = None if bgr is None else cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    raw = cv2.imdecode(depth, cv2.IMREAD_UNCHANGED)
    if raw is None or raw.dtype != np.uint16:
        raise ValueError("a keyframe's depth image is not a 16-bit PNG")
    d = raw.astype(np.float32) / np.float32(DEPTH_UNITS_PER_METRE)
    d[raw == 0] = np.nan
    return rgb, d


@dataclass
class Keyframe:
    """``id`` unique in its map; ``stamp`` of the frame [s]; features with 3-D points in the
    keyframe's camera frame; compressed images; ``words`` the bag-of-words counts (set by the
    place database)."""

    id: int
    stamp: float
    features: Features
    color_jpeg: np.ndarray
    depth_png: np.ndarray
    words: np.ndarray | None = field(default=None, repr=False)

    def images(self) -> tuple[np.ndarray | None, np.ndarray]:
        return decode_images(self.color_jpeg, self.depth_png)

    @property
    def nbytes(self) -> int:
        f = self.features
        return int(f.keypoints.nbytes + f.descriptors.nbytes + f.points.nbytes + f.octaves.nbytes
                   + self.color_jpeg.nbytes + self.depth_png.nbytes + (0 if self.words is None else self.words.nbytes))
