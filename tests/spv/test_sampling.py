"""Sampling the camera through the phosphenes' rays: P^C = K_C K_P^-1 P (paper §III-C1)."""
import math

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv.phosphene_map import MapSpec, PhospheneMap
from raspv_spv.sampling import Sampling


def test_rays_keep_their_angle_whatever_the_camera(camera):
    m = PhospheneMap.build(MapSpec(800, 800, 1000, "hexagonal", fov_deg=20.0))
    s = Sampling.build(m, camera)
    # angle of each phosphene seen from the eye = angle of its camera pixel seen from the camera
    ang_p = np.arctan((m.centres[:, 0] - 400) / m.focal_px)
    ang_c = np.arctan((s.uv[:, 0] - camera.cx) / camera.fx)
    assert np.allclose(ang_p, ang_c)
    assert np.allclose(s.uv, (camera.K @ np.linalg.inv(m.K) @ np.c_[m.centres, np.ones(m.count)].T).T[:, :2])
    # a 20 deg prosthesis inside a 60 deg camera: all inside, spread over about a third of the width
    assert s.inside.all()
    assert (s.uv[:, 0].max() - s.uv[:, 0].min()) / camera.width < 20 / 60 + 0.02
    assert np.allclose(np.linalg.norm(s.unit_rays, axis=1), 1.0) and np.allclose(s.rays[:, 2], 1.0)
    assert s.spacing_camera_px == m.spacing_x * camera.fx / m.focal_px


def test_rays_leaving_a_narrow_camera_are_outside():
    m = PhospheneMap.build(MapSpec(800, 800, 1000, "hexagonal", fov_deg=45.0))
    narrow = CameraIntrinsics.from_hfov(640, 480, 30.0)
    s = Sampling.build(m, narrow)
    half = math.tan(math.radians(15.0))
    expected = np.abs(s.rays[:, 0]) < half * 0.99
    assert not s.inside.all() and s.inside.any()
    assert np.all(s.inside[expected & (np.abs(s.rays[:, 1]) < 0.2)])
    # indices are always valid; values outside get the fill value
    img = np.full((480, 640), 9, np.uint8)
    v = s.sample(img, fill=0)
    assert np.all(v[s.inside] == 9) and np.all(v[~s.inside] == 0)


def test_images_at_another_resolution_are_sampled_as_the_same_camera(camera):
    m = PhospheneMap.build(MapSpec(800, 800, 200, "rectangular", fov_deg=40.0))
    s = Sampling.build(m, camera)
    xs = np.tile(np.arange(640, dtype=np.float32), (480, 1))
    half = xs[::2, ::2] / 2                       # 320x240 image holding the full-size column / 2
    full = s.sample(xs)
    small = s.sample(half)
    assert np.allclose(full / 2, small, atol=1.0)
