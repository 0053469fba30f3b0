"""Small bags built in the test process (no ROS graph)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from raspv_bags.from_frames import RgbdBagWriter
from raspv_common.intrinsics import CameraIntrinsics

T0 = 1_700_000_000.0


def make_rgbd_bag(path: Path, frames: int = 12, rate: float = 10.0, size=(64, 48), storage: str = "mcap",
                  with_pose: bool = False, camera: CameraIntrinsics | None = None) -> Path:
    """A bag of ``frames`` colour/depth/camera-info triples: colour frame i is a horizontal
    ramp plus i (so frames differ), depth a constant 1 + 0.1 i metres."""
    w, h = size
    cam = camera or CameraIntrinsics.from_hfov(w, h, 60.0)
    ramp = np.tile(np.linspace(0, 200, w, dtype=np.uint8)[None, :, None], (h, 1, 3))
    with RgbdBagWriter(path, storage, with_pose=with_pose) as out:
        for i in range(frames):
            pose = np.eye(4) if with_pose else None
            if pose is not None:
                pose[0, 3] = 0.1 * i
            out.add(T0 + i / rate, (ramp + i).astype(np.uint8), np.full((h, w), 1.0 + 0.1 * i, np.float32), cam, pose)
    return path


@pytest.fixture
def rgbd_bag(tmp_path) -> Path:
    return make_rgbd_bag(tmp_path / "rgbd")
