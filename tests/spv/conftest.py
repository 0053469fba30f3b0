"""Shared fixtures of the SPV tests: a private temporal-table cache and real RGB-D frames."""
from __future__ import annotations

import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.rgbd_files import read_color, read_depth_scaled


@pytest.fixture(autouse=True, scope="session")
def lut_cache(tmp_path_factory):
    """Temporal tables go to a per-session directory (built once per session, not in ~)."""
    path = tmp_path_factory.mktemp("raspv-cache")
    mp = pytest.MonkeyPatch()
    mp.setenv("RASPV_CACHE_DIR", str(path))
    yield path
    mp.undo()


@pytest.fixture(scope="session")
def tum_frame(data_dir):
    """TUM office desk (PrimeSense, 640x480): colour RGB, depth metres with NaN holes, camera."""
    color = read_color(data_dir / "rgbd" / "tum_color.png")
    depth = read_depth_scaled(data_dir / "rgbd" / "tum_depth.png", 1 / 5000)
    return color, depth, CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)


@pytest.fixture(scope="session")
def camera() -> CameraIntrinsics:
    """The paper's simulated Asus Xtion: 640x480, 60 deg horizontal field of view."""
    return CameraIntrinsics.from_hfov(640, 480, 60.0)


def uniform_rgb(value: int, camera: CameraIntrinsics) -> np.ndarray:
    return np.full((camera.height, camera.width, 3), value, np.uint8)
