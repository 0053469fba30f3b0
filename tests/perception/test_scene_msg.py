"""SceneStructure core object ↔ raspv_msgs/SceneStructure."""
import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Header

from raspv_camera.synthetic_scene import SyntheticRoom
from raspv_common.intrinsics import CameraIntrinsics
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from raspv_perception.scene_msg import structure_from_msg, structure_to_msg
from raspv_perception.scene_perception import ScenePerception
from raspv_perception.scene_structure import SceneStructure

K = CameraIntrinsics.from_hfov(320, 240, 60.0)


def round_trip(s: SceneStructure) -> SceneStructure:
    msg = structure_to_msg(s, Header(frame_id="camera"))
    wire = deserialize_message(serialize_message(msg), SceneStructureMsg)
    assert wire.header.frame_id == "camera"
    return structure_from_msg(wire)


def test_round_trip_keeps_the_scene():
    room = SyntheticRoom(K)
    s = ScenePerception().process(room.render(room.pose_at(10.0))[1], K).structure
    assert s.floor_found and s.planes and s.obstacles and len(s.free_floor)
    back = round_trip(s)
    assert back.floor_found and back.manhattan_found == s.manhattan_found
    np.testing.assert_allclose(back.floor_plane, s.floor_plane, atol=1e-6)
    np.testing.assert_allclose(back.camera_to_floor, s.camera_to_floor, atol=1e-6)
    np.testing.assert_allclose(back.up, s.up, atol=1e-6)
    assert back.camera_height == pytest.approx(s.camera_height, abs=1e-6)
    assert back.camera_pitch_deg == pytest.approx(s.camera_pitch_deg, abs=1e-4)
    np.testing.assert_allclose(back.manhattan_z, s.manhattan_z, atol=1e-6)
    assert [p.type for p in back.planes] == [p.type for p in s.planes]
    for a, b in zip(back.planes, s.planes):
        np.testing.assert_allclose(a.coefficients, b.coefficients, atol=1e-6)
        np.testing.assert_allclose(a.hull, b.hull, atol=1e-6)
        assert a.area == pytest.approx(b.area, rel=1e-6) and a.num_points == b.num_points
    for a, b in zip(back.obstacles, s.obstacles):
        np.testing.assert_allclose(a.min_floor, b.min_floor, atol=1e-6)
        assert a.height == pytest.approx(b.height, abs=1e-6)
    np.testing.assert_allclose(back.free_floor, s.free_floor, atol=1e-9)


def test_no_floor_travels_as_nan():
    back = round_trip(SceneStructure())
    assert not back.floor_found and not back.manhattan_found
    assert math.isnan(back.camera_height) and np.isnan(back.floor_plane).all()
    assert back.planes == [] and back.free_floor.shape == (0, 2)


def test_gravity_source_and_up_travel_without_a_floor():
    from raspv_perception.scene_structure import GravitySource

    s = SceneStructure(up=np.array([0.0, -0.8, -0.6]), gravity_source=GravitySource.IMU)
    back = round_trip(s)
    assert back.gravity_source == GravitySource.IMU and not back.floor_found
    np.testing.assert_allclose(back.up, [0.0, -0.8, -0.6], atol=1e-6)
    assert SceneStructureMsg.GRAVITY_IMU == GravitySource.IMU and SceneStructureMsg.GRAVITY_SUPPORT == GravitySource.SUPPORT
