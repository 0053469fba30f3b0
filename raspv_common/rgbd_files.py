"""Readers for the RGB-D file formats of public datasets (no ROS imports).

Every reader returns ``(color RGB uint8 (H, W, 3), depth float32 (H, W) metres with NaN where
there is no reading)``. Formats: TUM (uint16 PNG, metres = value / 5000), NYU Depth v2 raw
Kinect disparity PGM (byte-swapped 16-bit, metres = 351.3 / (1092.5 - d), d = 2047 invalid),
millimetre uint16 images (PCL/Kinect TIFF, RealSense PNG).
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from raspv_common.image_files import decode_image_file


class RGBDFormatError(ValueError):
    """A file could not be read as the colour or depth image it was said to be."""


def read_color(path: str | Path) -> np.ndarray:
    """Colour image file → RGB uint8 (H, W, 3)."""
    img = decode_image_file(path, cv2.IMREAD_COLOR)
    if img is None:
        raise RGBDFormatError(f"{path}: not a readable colour image")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def _read_uint16(path: str | Path) -> np.ndarray:
    raw = decode_image_file(path, cv2.IMREAD_UNCHANGED)
    if raw is None:
        raise RGBDFormatError(f"{path}: not a readable depth image")
    if raw.ndim != 2 or raw.dtype != np.uint16:
        raise RGBDFormatError(f"{path}: depth must be single-channel 16-bit, got {raw.dtype} with shape {raw.shape}")
    return raw


def depth_from_scaled_uint16(raw: np.ndarray, metres_per_unit: float) -> np.ndarray:
    """uint16 depth with 0 = no reading → float32 metres with NaN holes."""
    depth = raw.astype(np.float32) * np.float32(metres_per_unit)
    depth[raw == 0] = np.nan
    return depth


def read_depth_scaled(path: str | Path, metres_per_unit: float) -> np.ndarray:
    """uint16 depth image (PNG/TIFF) with a fixed scale (TUM: 1/5000, millimetres: 0.001)."""
    return depth_from_scaled_uint16(_read_uint16(path), metres_per_unit)


def read_nyu_disparity(path: str | Path) -> np.ndarray:
    """NYU Depth v2 raw Kinect disparity PGM → metres (NaN where d = 2047 or out of range)."""
    raw = _read_uint16(path).byteswap()  # stored little-endian despite the big-endian PGM header
    d = raw.astype(np.float32)
    with np.errstate(divide="ignore"):
        depth = np.float32(351.3) / (np.float32(1092.5) - d)
    depth[(raw >= 2047) | ~np.isfinite(depth) | (depth <= 0) | (depth > 12.0)] = np.nan
    return depth
