import math

import numpy as np
import pytest

from raspv_camera.synthetic_scene import SyntheticRoom
from raspv_common.intrinsics import CameraIntrinsics


def test_depth_is_exact_on_the_floor():
    intr = CameraIntrinsics.from_hfov(160, 120, 60.0)
    room = SyntheticRoom(intr, pitch_down_deg=30.0, boxes=[])
    pose = room.pose_at(0.0)
    color, depth = room.render(pose)
    assert color.shape == (120, 160, 3) and depth.dtype == np.float32
    # Bottom-centre pixel sees the floor: its 3-D point must have world z = 0.
    v, u = 119, 80
    p_c = intr.rays([u], [v])[0] * depth[v, u]
    p_w = pose[:3, :3] @ p_c + pose[:3, 3]
    assert p_w[2] == pytest.approx(0.0, abs=1e-4)
    # The optical axis meets the floor at distance eye_height / sin(pitch); depth is z in C.
    u0, v0 = 80, 60   # near the principal point (79.5, 59.5)
    ray = intr.rays([u0], [v0])[0]
    d_w = pose[:3, :3] @ ray
    t_floor = -pose[2, 3] / d_w[2]
    assert depth[v0, u0] == pytest.approx(t_floor, rel=1e-5)
    assert t_floor == pytest.approx(room.eye_height / math.sin(math.radians(30.0)), rel=0.02)


def test_camera_moves_along_its_loop():
    room = SyntheticRoom(CameraIntrinsics.from_hfov(32, 24, 60.0))
    a, b = room.pose_at(0.0), room.pose_at(2.0)
    assert np.linalg.norm(a[:3, 3] - b[:3, 3]) == pytest.approx(2 * room.walk_radius * math.sin(0.4 * 2 / room.walk_radius / 2), rel=1e-6)
    assert a[2, 3] == pytest.approx(room.eye_height)
