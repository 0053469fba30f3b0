"""Recordings made by each SDK's own recorder, in the test session (see raspv_camera.sdk_recordings)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from raspv_camera import sdk_imports
from raspv_camera.sdk_recordings import (SourceFrame, write_depthai_recording, write_openni2_dummy_recording,
                                         write_realsense_recording)
from raspv_common.intrinsics import CameraIntrinsics

T0 = 50.0            # recording clock of the first frame [s]
RATE = 30.0          # frames per second of the recordings
GRAVITY_C = np.array([0.0, -9.6, 2.0])     # accelerometer at rest in C: camera pitched down ~12°
DEPTHAI_LENS = (0.1, -0.2, 0.001, 0.002, 0.05, 0.01, 0.02, 0.03)   # OpenCV's rational model (8 coefficients)


@dataclass
class Recording:
    path: Path
    frames: list[SourceFrame]
    camera: CameraIntrinsics


def pattern_frames(n: int, size=(160, 120)) -> list[SourceFrame]:
    """Frames that differ everywhere: colour ramps shifted by i, depth 1.0 m + 1 mm per column + i mm."""
    w, h = size
    u = np.arange(w)[None, :]
    v = np.arange(h)[:, None]
    out = []
    for i in range(n):
        color = np.stack([(u + i) % 256 + 0 * v, (v * 2 + i) % 256 + 0 * u, np.full((h, w), (7 * i) % 256)], axis=2)
        depth = (1000 + u + i + 0 * v).astype(np.uint16)
        out.append(SourceFrame(color.astype(np.uint8), depth, T0 + i / RATE, GRAVITY_C))
    return out


def needs_openni2():
    if sdk_imports.openni2_library() is None:
        pytest.skip(f"the OpenNI2 library is not installed: {sdk_imports.OPENNI2_APT}")


@pytest.fixture(scope="session")
def realsense_recording(tmp_path_factory) -> Recording:
    frames = pattern_frames(20)
    K = CameraIntrinsics(160, 120, 140.0, 141.0, 79.5, 60.5)
    path = write_realsense_recording(tmp_path_factory.mktemp("rs") / "pattern.db3", frames, K, with_accel=True,
                                     name="Test D435I", serial="123456789012")
    return Recording(path, frames, K)


@pytest.fixture(scope="session")
def openni2_recording(tmp_path_factory):
    needs_openni2()
    return write_openni2_dummy_recording(tmp_path_factory.mktemp("oni") / "dummy.oni", 20)


@pytest.fixture(scope="session")
def depthai_recording(tmp_path_factory) -> Recording:
    frames = pattern_frames(20)
    K = CameraIntrinsics(160, 120, 150.0, 150.0, 80.0, 60.0)
    path = write_depthai_recording(tmp_path_factory.mktemp("dai") / "pattern", frames, K, lens=DEPTHAI_LENS)
    return Recording(path, frames, K)


@pytest.fixture(scope="session")
def tum_frame(data_dir):
    """The real TUM desk frame: (RGB, depth m registered to colour, PrimeSense intrinsics)."""
    from raspv_common.rgbd_files import read_color, read_depth_scaled

    return (read_color(data_dir / "rgbd" / "tum_color.png"), read_depth_scaled(data_dir / "rgbd" / "tum_depth.png", 1 / 5000),
            CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5))
