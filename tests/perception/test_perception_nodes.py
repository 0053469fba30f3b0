"""The scene and odometry nodes in real graphs."""
import math
import time

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, Image

from raspv_camera.synthetic_scene import SyntheticRoom, camera_rotation
from raspv_common import topics
from raspv_common.conversions import (array_to_image, image_to_array, intrinsics_to_camera_info, matrix_to_pose,
                                      pose_to_matrix, seconds_to_stamp)
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import SENSOR_QOS
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from raspv_perception import scene_labels as L
from raspv_perception.scene_msg import structure_from_msg
from std_msgs.msg import Header

pytestmark = pytest.mark.integration


def test_scene_node_on_the_synthetic_source(graph, probe):
    graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "scene"}]},
           "cam": {"ros__parameters": {"rate": 5.0, "width": 320, "height": 240, "walk_speed": 0.0,
                                       "eye_height": 1.5, "pitch_down_deg": 20.0}}})
    structures = probe.subscribe(topics.SCENE_STRUCTURE, SceneStructureMsg)
    labels = probe.subscribe(topics.SCENE_LABELS, Image)
    def stamp(m):
        return m.header.stamp.sec, m.header.stamp.nanosec

    # the two subscriptions match at different moments: take a depth frame both have seen
    msg = structures.wait(1, timeout=90, predicate=lambda m: stamp(m) in {stamp(x) for x in labels.messages})[0]
    s = structure_from_msg(msg)
    assert s.floor_found
    assert s.camera_height == pytest.approx(1.5, abs=0.02)
    assert s.camera_pitch_deg == pytest.approx(20.0, abs=0.5)
    lab = next(x for x in labels.messages if stamp(x) == stamp(msg))
    arr = image_to_array(lab)
    assert lab.encoding == "mono8" and arr.shape == (240, 320)
    assert (arr[200:] == L.FLOOR).mean() > 0.5          # the floor in front of the camera
    # run-time changes: a consistent one is applied, an inconsistent one refused with the reason
    [(_, ok, _)] = probe.set_params("scene", {"obstacle_margin": 0.3})
    assert ok
    [(_, ok, reason)] = probe.set_params("scene", {"first_floor_min_height": 2.5})
    assert not ok and "first_floor_min_height" in reason
    assert probe.get_params("scene", ["first_floor_min_height"])["first_floor_min_height"] == 1.0


def test_scene_node_refuses_impossible_settings_in_one_line(graph):
    g = graph({"launch": {"nodes": [{"kind": "scene"}]},
               "scene": {"ros__parameters": {"min_depth": 3.0, "max_depth": 2.0}}})
    g.wait_for_output(r"configuration error: min_depth \(3.0\) must be below max_depth \(2.0\)")
    g.proc.wait(timeout=30)
    assert g.stop() == 1 and "Traceback" not in g.output


def test_odometry_node_anchors_to_the_floor_and_follows_the_camera(graph, probe):
    K = CameraIntrinsics.from_hfov(320, 240, 60.0)
    room = SyntheticRoom(K)
    graph({"launch": {"nodes": [{"kind": "scene"}, {"kind": "odometry"}]},
           "odometry": {"ros__parameters": {"scale": 1.0}}})
    pub_info = probe.publisher(topics.CAMERA_INFO, CameraInfo, SENSOR_QOS, wait_for_subscribers=2, timeout=90)
    pub_color = probe.publisher(topics.COLOR, Image, SENSOR_QOS, wait_for_subscribers=1, timeout=60)
    pub_depth = probe.publisher(topics.DEPTH, Image, SENSOR_QOS, wait_for_subscribers=2, timeout=60)
    poses = probe.subscribe(topics.CAMERA_POSE, PoseStamped)

    def camera(t):
        T = np.eye(4)
        T[:3, :3] = camera_rotation(math.radians(10 + 8 * t), math.radians(25.0))
        T[:3, 3] = (-1.0 + 0.3 * t, -0.5, 1.6)
        return T

    truth = {}
    for i in range(30):
        t = 0.1 * i
        T = camera(t)
        rgb, depth = room.render(T)
        header = Header(stamp=seconds_to_stamp(100.0 + t), frame_id="camera")
        truth[(header.stamp.sec, header.stamp.nanosec)] = T
        pub_info.publish(intrinsics_to_camera_info(K, header))
        pub_color.publish(array_to_image(rgb, "rgb8", header))
        pub_depth.publish(array_to_image(depth, "32FC1", header))
        time.sleep(0.25)
        if len(poses.messages) >= 5:
            break
    got = poses.wait(5, timeout=60)
    # W: z up with the floor at z = 0 (the camera is 1.6 m up, looking 25° down, level sideways)
    for m in got:
        W = pose_to_matrix(m.pose)
        assert m.header.frame_id == "map"
        assert W[2, 3] == pytest.approx(1.6, abs=0.03)
        assert math.degrees(math.asin(-W[2, 2])) == pytest.approx(25.0, abs=0.7)
        assert abs(W[2, 0]) < 0.01
    # the motion between published poses matches the truth
    a, b = got[0], got[-1]
    ta = truth[(a.header.stamp.sec, a.header.stamp.nanosec)]
    tb = truth[(b.header.stamp.sec, b.header.stamp.nanosec)]
    est = np.linalg.inv(pose_to_matrix(a.pose)) @ pose_to_matrix(b.pose)
    true = np.linalg.inv(ta) @ tb
    assert np.linalg.norm(est[:3, 3] - true[:3, 3]) < 0.03


def test_spv_node_runs_the_scene_modes_from_the_scene_node(graph, probe):
    graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "scene"}, {"kind": "spv"}]},
           "cam": {"ros__parameters": {"rate": 5.0, "width": 320, "height": 240, "walk_speed": 0.3,
                                       "pitch_down_deg": 30.0}},
           "spv": {"ros__parameters": {"device": "optimist", "mode": "chess_floor", "temporal": False,
                                       "width": 200, "rate": 10.0}}})
    from raspv_msgs.msg import PhospheneFrame

    def levels_of(mode):
        frame = probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=90,
                                       predicate=lambda m: m.mode == mode and any(m.levels))
        return np.array(frame.levels)

    chess = levels_of("chess_floor")
    assert set(np.unique(chess)) == {0, 4, 7}          # off, half, full of 8 levels
    [(_, ok, _)] = probe.set_params("spv", {"mode": "wall_obstacles"})
    assert ok
    walls = levels_of("wall_obstacles")
    assert 4 in walls                                   # the walls at half level
    results = probe.set_params("spv", {"mode": "chess_wall_obstacles", "chess_tile": 1.0})
    assert all(ok for _, ok, _ in results)
    both = levels_of("chess_wall_obstacles")
    assert {4, 7} <= set(np.unique(both))


def test_scene_node_in_lockstep_takes_each_depth_frame_with_the_pose_of_its_stamp(graph, probe):
    """A scripted session's simulator publishes a frame's pose right after its images; on arrival
    the frame found its own pose, the previous frame's or none (the first frame), so lockstep runs
    of the office task parted. Looking 50° down, the floor is found only with the pose as prior."""
    K = CameraIntrinsics.from_hfov(160, 120, 60.0)
    T = np.eye(4)
    T[:3, :3] = camera_rotation(0.3, math.radians(50.0))
    T[:3, 3] = (-1.0, -0.5, 1.5)
    _, depth = SyntheticRoom(K).render(T)
    graph({"launch": {"nodes": [{"kind": "scene"}]}, "scene": {"ros__parameters": {"lockstep": True}}})
    structures = probe.subscribe(topics.SCENE_STRUCTURE, SceneStructureMsg, wait_for_publishers=1, timeout=90)
    pub_info = probe.publisher(topics.CAMERA_INFO, CameraInfo, SENSOR_QOS, wait_for_subscribers=1, timeout=60)
    pub_pose = probe.publisher(topics.CAMERA_POSE, PoseStamped, SENSOR_QOS, wait_for_subscribers=1, timeout=60)
    pub_depth = probe.publisher(topics.DEPTH, Image, SENSOR_QOS, wait_for_subscribers=1, timeout=60)
    header = Header(stamp=seconds_to_stamp(0.1), frame_id="camera")
    pub_info.publish(intrinsics_to_camera_info(K, header))
    pub_info.publish(intrinsics_to_camera_info(K, header))         # best effort: once more, before the image
    pub_depth.publish(array_to_image(depth, "32FC1", header))
    with pytest.raises(TimeoutError):                               # it waits for the frame's pose
        structures.wait(1, timeout=1.5)
    pub_pose.publish(PoseStamped(header=Header(stamp=header.stamp, frame_id="map"), pose=matrix_to_pose(T)))
    s = structure_from_msg(structures.wait(1, timeout=30)[0])
    assert s.floor_found and s.camera_height == pytest.approx(1.5, abs=0.02)
