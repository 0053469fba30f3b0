"""Shared fixtures of the SPV tests: a private temporal-table cache and real RGB-D frames."""
from __future__ import annotations

import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.rgbd_files import read_color, read_depth_scaled


# The spv node's start-up configurations in the integration tests (tests/spv/test_spv_node*.py):
# their temporal tables are built here, once, so a node started on a loaded machine does not
# spend its tests' time budget building them (building and caching is tested in test_temporal_lut).
NODE_START_CONFIGS = [
    {"device": "argus_iii", "rate": 25.0, "width": 300, "mode": "depth"},
    {"rate": 20.0, "width": 200},
    {"device": "argus_ii", "rate": 25.0, "width": 400},
]


@pytest.fixture(autouse=True, scope="session")
def lut_cache(private_cache):
    """Temporal tables go to the session's private cache (built once per session, not in ~)."""
    return private_cache


@pytest.fixture(scope="module")
def warm_node_tables(lut_cache):
    """Build the temporal tables of :data:`NODE_START_CONFIGS` into the session's cache."""
    from raspv_spv.config import config_from_node_params
    from raspv_spv.simulator import PhospheneSimulator
    from raspv_spv.spv_params import PARAMS

    defaults = {p.name: p.default for p in PARAMS}
    for overrides in NODE_START_CONFIGS:
        PhospheneSimulator(config_from_node_params({**defaults, **overrides}))
    return lut_cache


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
