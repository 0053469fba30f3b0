"""Real RGB-D frames (tests/data/rgbd, provenance in its README) and synthetic scenes for the
perception tests."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.rgbd_files import read_color, read_depth_scaled, read_nyu_disparity

DATA = Path(__file__).resolve().parents[1] / "data" / "rgbd"
KINECT_DEFAULT = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
PCL_KINECT = CameraIntrinsics(640, 480, 525.0, 525.0, 320.0, 240.0)


@pytest.fixture(scope="session")
def tum_frame():
    return read_color(DATA / "tum_color.png"), read_depth_scaled(DATA / "tum_depth.png", 1 / 5000), KINECT_DEFAULT


@pytest.fixture(scope="session")
def nyu_frame():
    return read_color(DATA / "nyu_color.ppm"), read_nyu_disparity(DATA / "nyu_depth.pgm"), KINECT_DEFAULT


@pytest.fixture(scope="session")
def kinect_frames():
    """The three consecutive PCL Kinect frames: [(rgb, depth m, intrinsics), ...] in time order."""
    out = []
    for depth_path in sorted((DATA / "kinect_table").glob("*_depth.tiff")):
        rgb_path = depth_path.with_name(depth_path.name.replace("_depth", "_rgb"))
        out.append((read_color(rgb_path), read_depth_scaled(depth_path, 0.001), PCL_KINECT))
    return out


def plane_depth(intrinsics: CameraIntrinsics, normal, d) -> np.ndarray:
    """Depth [m] of the plane n·p + d = 0 (camera frame) seen by ``intrinsics``; NaN where the
    ray misses it (behind the camera)."""
    u, v = np.meshgrid(np.arange(intrinsics.width), np.arange(intrinsics.height))
    rays = intrinsics.rays(u, v)                      # z = 1
    n = np.asarray(normal, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = -d / (rays @ n)
    z[~(z > 0)] = np.nan
    return z.reshape(intrinsics.height, intrinsics.width).astype(np.float32)
