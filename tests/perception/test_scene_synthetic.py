"""Scene perception on the analytic room (exact depth and pose): floor frame, Manhattan axes,
plane classes, obstacles, free floor, labels, pose prior, tracking and bad input."""
import math

import numpy as np
import pytest

from raspv_camera.synthetic_scene import SyntheticRoom, camera_rotation
from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception import scene_labels as L
from raspv_perception.scene_config import SceneConfig
from raspv_perception.scene_perception import ScenePerception
from raspv_perception.scene_structure import GravitySource, PlaneType

K = CameraIntrinsics.from_hfov(640, 480, 60.0)


@pytest.fixture(scope="module")
def room():
    return SyntheticRoom(K)


def pose(x, y, z, yaw_deg, pitch_down_deg):
    T = np.eye(4)
    T[:3, :3] = camera_rotation(math.radians(yaw_deg), math.radians(pitch_down_deg))
    T[:3, 3] = (x, y, z)
    return T


def pixel_of(world_point, T):
    p = np.linalg.inv(T) @ np.append(world_point, 1.0)
    u, v, _ = K.project(p[:3])
    assert K.contains(u, v).all(), f"{world_point} is out of view"
    return int(round(v[0])), int(round(u[0]))


def test_floor_frame_and_manhattan_axes_along_a_walk(room):
    perception = ScenePerception()
    for t in np.arange(0.0, 12.0, 1.5):
        T = room.pose_at(t)
        s = perception.process(room.render(T)[1], K).structure
        assert s.floor_found and s.gravity_source == GravitySource.FLOOR
        assert s.camera_height == pytest.approx(1.6, abs=0.01)
        assert s.camera_pitch_deg == pytest.approx(15.0, abs=0.2)
        assert s.camera_roll_deg == pytest.approx(0.0, abs=0.2)
        # F's y axis is world-down, its origin is the floor point below the camera
        F_in_world = T @ s.camera_to_floor
        np.testing.assert_allclose(F_in_world[:3, 1], [0, 0, -1], atol=0.005)
        np.testing.assert_allclose(F_in_world[:3, 3], [T[0, 3], T[1, 3], 0.0], atol=0.02)
        # Manhattan axes: the room's axes, whatever the heading
        assert s.manhattan_found
        mz = T[:3, :3] @ s.manhattan_z
        assert abs(mz[2]) < 0.01
        assert min(math.degrees(math.atan2(mz[1], mz[0])) % 90, 90 - math.degrees(math.atan2(mz[1], mz[0])) % 90) < 1.0
        assert np.dot(s.manhattan_x, s.manhattan_z) == pytest.approx(0.0, abs=1e-9)


def test_cabinet_walls_and_floor_in_view(room):
    T = pose(0.0, 0.0, 1.6, 0.0, 25.0)          # facing +x: the cabinet (2.3–3.1 m, 0.75 m high), wall at 4 m
    rgb, depth = room.render(T)
    result = ScenePerception().process(depth, K)
    s, labels = result.structure, result.labels
    assert labels.shape == depth.shape and labels.dtype == np.uint8
    tops = [p for p in s.planes_of(PlaneType.HORIZONTAL) if abs(p.height - 0.75) < 0.02]
    assert tops and tops[0].area == pytest.approx(0.8 * 1.2, rel=0.15)
    walls = s.planes_of(PlaneType.WALL)
    assert walls and walls[0].coefficients[3] == pytest.approx(4.0, abs=0.02)
    cabinet = min(s.obstacles, key=lambda o: o.distance)
    assert cabinet.height == pytest.approx(0.75, abs=0.03)
    assert cabinet.distance == pytest.approx(2.3, abs=0.05)
    assert cabinet.min_floor[0] == pytest.approx(-0.6, abs=0.05) and cabinet.max_floor[0] == pytest.approx(0.6, abs=0.05)
    assert cabinet.min_floor[2] == pytest.approx(2.3, abs=0.05)
    # per-pixel classes at known world points
    assert labels[pixel_of([2.7, 0.0, 0.75], T)] == L.HORIZONTAL       # cabinet top
    assert labels[pixel_of([2.3, 0.3, 0.4], T)] == L.OBSTACLE           # cabinet front
    assert labels[pixel_of([3.99, 1.5, 1.2], T)] == L.WALL
    assert labels[pixel_of([1.7, 0.5, 0.0], T)] == L.FLOOR
    assert labels[pixel_of([2.22, 0.0, 0.0], T)] == L.FLOOR_BLOCKED    # within the margin of the cabinet
    # free floor polygon (x, z in F = right, forward here) holds the near floor, not the cabinet's footprint
    import cv2
    poly = s.free_floor.astype(np.float32)
    assert cv2.pointPolygonTest(poly, (0.0, 1.9), False) > 0
    assert cv2.pointPolygonTest(poly, (0.0, 2.7), False) < 0


def test_pose_prior_finds_a_floor_seen_steeply(room):
    T = pose(0.0, -1.0, 1.6, 0.0, 60.0)
    depth = room.render(T)[1]
    assert not ScenePerception().process(depth, K).structure.floor_found   # beyond the first-floor tilt
    perception = ScenePerception()
    s = perception.process(depth, K, world_from_camera=T).structure
    assert s.floor_found and s.camera_height == pytest.approx(1.6, abs=0.01)
    assert s.camera_pitch_deg == pytest.approx(60.0, abs=0.3)
    # tracked from now on, also without the pose
    assert perception.process(depth, K).structure.floor_found


def test_a_floor_step_breaks_the_track_until_it_is_dropped(room):
    perception = ScenePerception(SceneConfig(track_lost_frames=2))
    assert perception.process(room.render(pose(0, 0, 1.6, 90, 20))[1], K).structure.floor_found
    lower = room.render(pose(0, 0, 1.3, 90, 20))[1]           # 0.3 m lower: not the tracked floor
    assert not perception.process(lower, K).structure.floor_found
    assert not perception.process(lower, K).structure.floor_found   # second miss drops the track
    s = perception.process(lower, K).structure
    assert s.floor_found and s.camera_height == pytest.approx(1.3, abs=0.01)


def test_wall_only_view_reports_no_floor(room):
    T = pose(3.5, 0.0, 1.6, 0.0, 0.0)          # 0.5 m from the wall at x = 4, level
    depth = room.render(T)[1]
    result = ScenePerception().process(depth, K)
    s = result.structure
    assert not s.floor_found and math.isnan(s.camera_height)
    assert not s.obstacles and len(s.free_floor) == 0
    walls = s.planes_of(PlaneType.WALL)
    assert walls and walls[0].coefficients[3] == pytest.approx(0.5, abs=0.01)
    assert (result.labels == L.WALL).mean() > 0.9


@pytest.mark.parametrize("kind", ["nan", "zeros", "inf", "noise", "far"])
def test_degenerate_depth_gives_an_empty_scene(kind):
    rng = np.random.default_rng(1)
    depth = {"nan": np.full((480, 640), np.nan), "zeros": np.zeros((480, 640)), "inf": np.full((480, 640), np.inf),
             "noise": rng.uniform(0.5, 6.0, (480, 640)), "far": np.full((480, 640), 50.0)}[kind].astype(np.float32)
    result = ScenePerception().process(depth, K)
    assert not result.structure.floor_found
    if kind != "noise":
        assert not result.labels.any() and not result.structure.planes


def test_holes_in_the_depth_are_ignored(room):
    T = room.pose_at(3.0)
    depth = room.render(T)[1].copy()
    rng = np.random.default_rng(2)
    depth[rng.random(depth.shape) < 0.3] = np.nan         # 30 % missing readings
    depth[100:140, :] = 0.0                               # a band of zeros
    result = ScenePerception().process(depth, K)
    assert result.structure.floor_found
    assert result.structure.camera_height == pytest.approx(1.6, abs=0.02)
    assert (result.labels[100:140] == L.NONE).all()


def test_bad_inputs_are_refused_with_a_reason():
    perception = ScenePerception()
    with pytest.raises(ValueError, match="camera model"):
        perception.process(np.zeros((240, 320), np.float32), K)
    with pytest.raises(ValueError, match="4x4"):
        perception.process(np.zeros((480, 640), np.float32), K, world_from_camera=np.eye(3))
    with pytest.raises(ValueError, match="stride"):
        SceneConfig(stride=0)
    with pytest.raises(ValueError, match="min_depth"):
        SceneConfig(min_depth=5.0, max_depth=4.0)
