"""Camera mounting: the first-floor limits of head, chest, hand and robot cameras, and gravity
from an IMU finding the floor at any height — on real frames taken 0.72 m above the floor and
on renders from 0.3–1.0 m.

The PCL Kinect frames (tests/data/rgbd) look 46° down at a carpet 0.72 m below the camera with a
laptop and a box on it; the floor beyond is the same plane (see test_scene_real). A head-mounted
prior (1.0–2.0 m, ≤ 40°) rejects it; the hand and robot mountings accept it.
"""
import math

import numpy as np
import pytest

from raspv_perception.floor import angle_deg
from raspv_perception.scene_config import MOUNTINGS, SceneConfig
from raspv_perception.scene_node import config_from_params
from raspv_perception.scene_params import PARAMS
from raspv_perception.scene_perception import ScenePerception
from raspv_perception.scene_structure import GravitySource

LAPTOP_PIXELS = (slice(150, 315), slice(135, 370))
BOX_PIXELS = (slice(185, 310), slice(380, 500))


def test_mountings_set_the_first_floor_limits():
    assert set(MOUNTINGS) == {"head", "chest", "hand", "robot"}
    head = SceneConfig().with_mounting("head")
    assert (head.first_floor_min_height, head.first_floor_max_height, head.first_floor_max_angle_deg) == (1.0, 2.0, 40.0)
    low = SceneConfig().with_mounting("robot")
    assert low.first_floor_min_height <= 0.4 and low.first_floor_max_height >= 1.0
    for name, m in MOUNTINGS.items():
        assert 0 < m.min_height < m.max_height and 0 < m.max_tilt_deg < 90, name
    custom = SceneConfig(first_floor_min_height=0.5, first_floor_max_height=0.9)
    assert custom.with_mounting("custom") is custom
    with pytest.raises(ValueError, match="unknown mounting"):
        SceneConfig().with_mounting("shoulder")


def test_scene_node_parameters_choose_the_mounting():
    defaults = {p.name: p.default for p in PARAMS}
    assert defaults["mounting"] == "head"
    assert config_from_params({**defaults, "mounting": "hand"}).first_floor_min_height == MOUNTINGS["hand"].min_height
    custom = config_from_params({**defaults, "mounting": "custom", "first_floor_min_height": 0.5})
    assert custom.first_floor_min_height == 0.5
    with pytest.raises(ValueError, match="applies with mounting 'custom'"):
        config_from_params({**defaults, "first_floor_min_height": 0.5})


@pytest.mark.parametrize("mounting", ["chest", "hand", "robot"])     # 0.72 m, 46°: inside chest's 0.7–1.6 m, ≤ 50°
def test_real_frames_from_072_m_find_the_floor_with_a_low_mounting(kinect_frames, mounting):
    perception = ScenePerception(SceneConfig().with_mounting(mounting))
    K = kinect_frames[0][2]
    for _, depth, _ in kinect_frames:
        result = perception.process(depth, K)
        s = result.structure
        assert s.floor_found and s.gravity_source == GravitySource.FLOOR
        assert s.camera_height == pytest.approx(0.72, abs=0.02)
        assert s.camera_pitch_deg == pytest.approx(46.0, abs=2.0)
        # the laptop and the box are still obstacles standing on it
        hits = set()
        for o in s.obstacles:
            u, v, _ = K.project(o.centroid)
            for name, (rows, cols) in (("laptop", LAPTOP_PIXELS), ("box", BOX_PIXELS)):
                if rows.start <= v[0] < rows.stop and cols.start <= u[0] < cols.stop:
                    hits.add(name)
        assert hits == {"laptop", "box"}


def test_real_frames_from_072_m_find_no_floor_with_a_head_mounting(kinect_frames):
    s = ScenePerception(SceneConfig().with_mounting("head")).process(kinect_frames[0][1], kinect_frames[0][2]).structure
    assert not s.floor_found and s.gravity_source == GravitySource.SUPPORT


@pytest.fixture(scope="module")
def low_views():
    """Apartment renders (320×240, depth-sensor noise on) from eye heights 0.4, 0.7 and 1.0 m with
    the head pitched 35° down: (frame, true camera height, true up in C)."""
    from raspv_sim.avatar import AvatarConfig
    from raspv_sim.depth_sensor import DepthSensorConfig
    from raspv_sim.simulator import SimConfig, Simulation

    views = []
    for eye in (0.4, 0.7, 1.0):
        with Simulation("apartment", SimConfig(width=320, height=240, avatar=AvatarConfig(eye_height=eye),
                                               depth_sensor=DepthSensorConfig())) as sim:
            x, y = sim.spec.spawn_position
            f = sim.render_from(x, y, math.radians(sim.spec.spawn_yaw), head_pitch=math.radians(35))
            R = f.world_from_camera[:3, :3]
            views.append((f, float(f.world_from_camera[2, 3]), R.T @ np.array([0.0, 0.0, 1.0])))
    return views


def test_rendered_low_cameras_need_a_low_mounting_or_an_imu(low_views):
    for f, height, up in low_views:
        for mounting in ("hand", "robot"):
            s = ScenePerception(SceneConfig().with_mounting(mounting)).process(f.depth, f.intrinsics).structure
            assert s.floor_found and s.camera_height == pytest.approx(height, abs=0.03), (mounting, height)
        head = ScenePerception(SceneConfig().with_mounting("head")).process(f.depth, f.intrinsics).structure
        assert not head.floor_found, height
        # a chest harness (0.7–1.6 m): the floor from 0.7 and 1.0 m, not from 0.4 m
        chest = ScenePerception(SceneConfig().with_mounting("chest")).process(f.depth, f.intrinsics).structure
        assert chest.floor_found == (height >= MOUNTINGS["chest"].min_height - 0.02), height
        if chest.floor_found:
            assert chest.camera_height == pytest.approx(height, abs=0.03)
        # gravity from an IMU (here the true one, tilted 5° as an accelerometer's error could) finds
        # the floor at any height, whatever the mounting says
        tilt = np.array([[1, 0, 0], [0, math.cos(0.087), -math.sin(0.087)], [0, math.sin(0.087), math.cos(0.087)]])
        imu = ScenePerception(SceneConfig().with_mounting("head")).process(f.depth, f.intrinsics,
                                                                           gravity_up=tilt @ up).structure
        assert imu.floor_found and imu.camera_height == pytest.approx(height, abs=0.03)
        assert imu.gravity_source == GravitySource.FLOOR and angle_deg(imu.up, up) < 2.0


def test_imu_gravity_without_a_floor_in_view_classifies_with_it(low_views):
    f, _, up = low_views[0]
    K = f.intrinsics
    v, u = np.mgrid[0:K.height, 0:K.width]
    z = f.depth
    world_z = (f.world_from_camera[2, :3] @ np.stack([(u - K.cx) / K.fx * z, (v - K.cy) / K.fy * z, z]).reshape(3, -1)
               ).reshape(z.shape) + f.world_from_camera[2, 3]
    depth = np.where(world_z > 0.15, z, np.nan).astype(np.float32)      # the floor taken out of view
    s = ScenePerception().process(depth, f.intrinsics, gravity_up=up).structure
    assert not s.floor_found and s.gravity_source == GravitySource.IMU
    np.testing.assert_allclose(s.up, up / np.linalg.norm(up), atol=1e-9)
    with pytest.raises(ValueError, match="gravity_up"):
        ScenePerception().process(depth, f.intrinsics, gravity_up=[0.0, 0.0, 0.0])


def test_a_floor_found_without_gravity_is_searched_again_once_the_imu_arrives():
    from raspv_perception.floor import FloorTracker

    cfg = SceneConfig().with_mounting("robot")
    tracker = FloorTracker(cfg)
    tracker.expectation(None)                                    # no IMU yet: the mounting's limits
    tracker.update(np.array([0.0, -1.0, 0.0, 1.07]), None)        # e.g. a desk top 1.07 m below
    up = np.array([0.0, -1.0, 0.0])
    e = tracker.expectation(None, gravity_up=up)                 # gravity arrives: search again, any height
    assert e.predicted is None and e.max_height == cfg.max_depth
    tracker.update(np.array([0.0, -1.0, 0.0, 1.79]), None)
    assert tracker.expectation(None, gravity_up=up).predicted is not None    # now it is tracked
