"""The camera: depth and intrinsics agree with PyBullet ray casts, for both renderers; labels come
from the segmentation buffer; the head turns the camera independently of the base."""
from __future__ import annotations

import math

import numpy as np
import pytest

from raspv_sim.avatar import head_quaternion
from raspv_sim.simulator import SimConfig, Simulation

RENDERERS = ["tiny", "egl"]


@pytest.fixture(scope="module", params=RENDERERS)
def sim(request):
    s = Simulation("apartment", SimConfig(width=160, height=120, renderer=request.param))
    yield s
    s.close()


def ray_depth(sim: Simulation, us: np.ndarray, vs: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cast a ray through each pixel (u, v) with the published intrinsics; return the hit's
    z in the camera frame and the body id (−1: nothing within 50 m)."""
    rays = sim.intrinsics.rays(us, vs)                      # (N, 3), z = 1, camera frame
    dirs = rays @ T[:3, :3].T
    origin = T[:3, 3]
    hits = sim.client.rayTestBatch([origin.tolist()] * len(dirs), (origin + 50.0 * dirs).tolist())
    body = np.array([h[0] for h in hits])
    pts = np.array([h[3] for h in hits])
    z = (pts - origin) @ T[:3, 2]
    z[body < 0] = np.nan
    return z, body


def test_published_intrinsics_are_the_papers_camera(sim):
    K = sim.intrinsics
    assert (K.width, K.height) == (160, 120)
    assert K.fx == pytest.approx(160 / (2 * math.tan(math.radians(30))))
    assert (K.cx, K.cy) == (79.5, 59.5)


@pytest.mark.parametrize("pose", [(6.5, 3.6, 20.0, 0.0), (9.0, 5.0, -120.0, 25.0)])
def test_depth_and_intrinsics_agree_with_ray_casts(sim, pose):
    x, y, yaw, pitch = pose
    sim.avatar.teleport(x, y, math.radians(yaw))
    sim.set_head(head_quaternion(0.0, math.radians(pitch), 0.0))
    frame = sim.render()
    T = frame.world_from_camera
    v, u = np.mgrid[2:118:5, 2:158:5]
    u, v = u.ravel(), v.ravel()
    z_ray, body = ray_depth(sim, u, v, T)
    z_img = frame.depth[v, u]
    # compare where the depth image is locally smooth (no object boundary through the pixel)
    d = frame.depth
    smooth = np.array([np.nanmax(np.abs(d[vv - 1:vv + 2, uu - 1:uu + 2] - d[vv, uu])) < 0.02 * d[vv, uu]
                       if np.isfinite(d[vv, uu]) else False for uu, vv in zip(u, v)])
    both = smooth & np.isfinite(z_ray) & np.isfinite(z_img)
    assert both.sum() > 0.5 * len(u)
    err = np.abs(z_ray[both] - z_img[both])
    assert np.median(err) < 0.002 and err.max() < 0.01 + 0.003 * z_img[both].max()
    # and the ray's body has the label the image shows
    labels = sim.world.class_lut[body[both] + 1]
    assert (labels == frame.labels[v[both], u[both]]).mean() > 0.97


def test_a_known_world_point_lands_on_its_pixel_with_its_depth(sim):
    """The top front-right corner region of the coffee table (spec: centre (10, 4), 0.6 × 1.1 m,
    0.42 m high) seen from the corridor's mouth: project a point on the table top with the
    published intrinsics and pose, and find that pixel labelled 'table' at that depth."""
    sim.avatar.teleport(7.0, 4.0, 0.0)
    sim.set_head(head_quaternion(0.0, math.radians(30), 0.0))
    frame = sim.render()
    point = np.array([9.8, 4.2, 0.42, 1.0])                 # on the table top, W
    pc = np.linalg.inv(frame.world_from_camera) @ point
    u, v, z = sim.intrinsics.project(pc[None, :3])
    ui, vi = int(round(u[0])), int(round(v[0]))
    assert 0 <= ui < 160 and 0 <= vi < 120
    assert sim.classes[frame.labels[vi, ui]] == "table"
    assert frame.depth[vi, ui] == pytest.approx(z[0], abs=0.01)


def test_depth_is_nan_beyond_the_far_plane_and_colour_still_rendered():
    with Simulation("stairs", SimConfig(width=64, height=48, renderer="tiny", far=4.0)) as s:
        frame = s.render()                                   # the far wall is 11 m away
        far_rows = frame.depth[18:24]                        # just below the horizon: wall beyond 4 m
        assert np.isnan(far_rows).all()
        assert (frame.labels[18:24] == s.classes.index("wall")).any()
        assert np.nanmax(frame.depth) <= 4.0


def test_head_orientation_turns_the_camera_not_the_base(sim):
    sim.avatar.teleport(3.0, 3.8, 0.0)
    sim.set_head((0.0, 0.0, 0.0, 1.0))
    T0 = sim.avatar.world_from_camera()
    assert T0[:3, 2] == pytest.approx([1.0, 0.0, 0.0], abs=1e-9)       # looks along the base's x
    assert T0[:3, 0] == pytest.approx([0.0, -1.0, 0.0], abs=1e-9)      # image right = base's −y
    assert T0[2, 3] == pytest.approx(1.6)                              # eye height
    sim.set_head(head_quaternion(0.0, 0.0, math.radians(40)))          # look 40° left
    T1 = sim.avatar.world_from_camera()
    assert math.degrees(math.atan2(T1[1, 2], T1[0, 2])) == pytest.approx(40.0)
    sim.set_head(head_quaternion(0.0, math.radians(30), 0.0))          # look 30° down
    T2 = sim.avatar.world_from_camera()
    assert math.degrees(math.asin(-T2[2, 2])) == pytest.approx(30.0)
    sim.set_head(head_quaternion(math.radians(15), 0.0, 0.0))          # tilt the head right
    T3 = sim.avatar.world_from_camera()
    assert math.degrees(math.asin(-T3[2, 0])) == pytest.approx(15.0)   # image right dips below the horizon
    assert (sim.avatar.x, sim.avatar.y, sim.avatar.yaw) == (3.0, 3.8, 0.0)
    with pytest.raises(ValueError, match="non-zero quaternion"):
        sim.set_head((0.0, 0.0, 0.0, 0.0))
    sim.set_head((0.0, 0.0, 0.0, 1.0))


def test_labels_name_the_objects_in_view(sim):
    sim.avatar.teleport(6.5, 3.6, math.radians(20))
    sim.set_head(head_quaternion(0.0, math.radians(15), 0.0))
    frame = sim.render()
    seen = {sim.classes[i] for i in np.unique(frame.labels)}
    assert {"floor", "wall", "sofa", "table", "chair", "shelf", "lamp"} <= seen
    assert frame.labels.dtype == np.uint8 and frame.rgb.dtype == np.uint8 and frame.depth.dtype == np.float32
    # the sofa is blue, the floor is not black: colour and labels line up
    sofa = frame.labels == sim.classes.index("sofa")
    r, g, b = (frame.rgb[sofa].astype(float).mean(axis=0))
    assert b > r and b > g


def test_a_margin_widens_the_image_at_the_same_focal_length_and_stays_exact():
    """margin_deg renders 10° more on every side at the nominal camera's focal length: the same
    scene, more of it; depth in the margin agrees with ray casts like the centre's."""
    config = SimConfig(width=160, height=120, margin_deg=10.0, renderer="egl")
    nominal = SimConfig(width=160, height=120).intrinsics()
    with Simulation("apartment", config) as s:
        K = s.intrinsics
        assert K.fx == pytest.approx(nominal.fx) and K.fy == pytest.approx(nominal.fy)
        assert K.hfov_deg == pytest.approx(nominal.hfov_deg + 20.0, abs=0.3)
        assert K.vfov_deg == pytest.approx(nominal.vfov_deg + 20.0, abs=0.3)
        assert (K.cx, K.cy) == ((K.width - 1) / 2, (K.height - 1) / 2)
        s.avatar.teleport(6.5, 3.6, math.radians(20.0))
        frame = s.render()
        assert frame.depth.shape == (K.height, K.width) and frame.rgb.shape[:2] == (K.height, K.width)
        v, u = np.mgrid[2:K.height - 2:6, 2:K.width - 2:6]
        u, v = u.ravel(), v.ravel()
        margin = (np.abs(u - K.cx) > nominal.width / 2) | (np.abs(v - K.cy) > nominal.height / 2)
        z_ray, _ = ray_depth(s, u, v, frame.world_from_camera)
        z_img = frame.depth[v, u]
        both = margin & np.isfinite(z_ray) & np.isfinite(z_img)
        assert both.sum() > 50
        assert np.median(np.abs(z_ray[both] - z_img[both])) < 0.002
    with pytest.raises(ValueError, match="170 deg"):
        SimConfig(width=160, height=120, hfov_deg=150.0, margin_deg=20.0).intrinsics()
