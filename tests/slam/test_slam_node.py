"""The `slam` node on a real recording (TUM fr1/rpy: 1.6 s of a hand-held camera turning 53° away
and back, tests/data/tum_fr1_rpy_pan): a world-fixed floor point stays put in the map frame
across the pan; its tf reaches the camera; the tracking state reaches /spv/status; the map is
autosaved, saved on request and when the graph stops.

The test is the recording's source: it publishes each frame (colour, depth, camera info with TUM's
fr1 lens distortion, with the camera's mounting on /tf_static as a camera node does) once the node
has answered the previous one on /slam/state, so every frame is processed whatever the machine's
load (the node itself drops frames that come while it works, as it should live)."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header, String
from tf2_msgs.msg import TFMessage

from raspv_bags.from_frames import CAMERA_DISTORTION, CAMERA_PRESETS, CAMERA_ROLLING_SHUTTER, discover_frames, read_depth
from raspv_common import frames, topics
from raspv_common.conversions import (array_to_image, intrinsics_to_camera_info, pose_to_matrix, seconds_to_stamp,
                                      stamp_to_seconds)
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import LATCHED_QOS, SENSOR_QOS, TF_STATIC_QOS
from raspv_common.rgbd_files import read_color
from raspv_common.tf_messages import transform_msg
from tests.slam.pan_floor import DATA, FLOOR_TOLERANCE_M, PAN_DEG, floor_point_moved
from tests.tf.test_tf_tree_graphs import FrameWatch

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_slam_keeps_a_floor_point_in_the_map_frame_across_a_pan(graph, probe, tmp_path):
    recording = discover_frames(DATA)
    K = CameraIntrinsics(640, 480, *CAMERA_PRESETS["tum-fr1"])
    watch = FrameWatch(probe)
    poses = probe.subscribe(topics.CAMERA_POSE, PoseStamped)
    states = probe.subscribe(topics.SLAM_STATE, String, qos=LATCHED_QOS)
    status = probe.subscribe(topics.SPV_STATUS, String, qos=LATCHED_QOS)
    g = graph({"launch": {"nodes": [{"kind": "slam"}, {"kind": "spv"}]},
               "slam": {"ros__parameters": {"save_to": str(tmp_path / "map"), "gravity_from_floor": False,
                                            "autosave_period": 1.0,
                                            "rolling_shutter_readout": CAMERA_ROLLING_SHUTTER["tum-fr1"]}},
               "spv": {"ros__parameters": {"mode": "depth", "headless": True}}})
    mounting = probe.publisher(topics.TF_STATIC, TFMessage, qos=TF_STATIC_QOS)
    mounting.publish(TFMessage(transforms=[transform_msg(p, c, T, seconds_to_stamp(recording.pairs[0].stamp_s))
                                           for p, c, T in frames.camera_mounting_edges(frames.CAMERA_OPTICAL)]))
    # subscribers: this probe's frame watch, the slam node, and (depth, camera info) the spv node
    pubs = {t: probe.publisher(t, cls, qos=SENSOR_QOS, wait_for_subscribers=n, timeout=120)
            for t, cls, n in ((topics.CAMERA_INFO, CameraInfo, 3), (topics.COLOR, Image, 2), (topics.DEPTH, Image, 3))}
    for pair in recording.pairs:                 # each frame once the node answered the one before
        header = Header(stamp=seconds_to_stamp(pair.stamp_s), frame_id=frames.CAMERA_OPTICAL)
        messages = [(topics.CAMERA_INFO, intrinsics_to_camera_info(K, header, CAMERA_DISTORTION["tum-fr1"])),
                    (topics.COLOR, array_to_image(read_color(pair.color), "rgb8", header)),
                    (topics.DEPTH, array_to_image(read_depth(pair.depth, recording.depth_format,
                                                             recording.depth_scale), "32FC1", header))]
        answered = lambda m, t=pair.stamp_s: abs(json.loads(m.data)["stamp"] - t) < 1e-3  # noqa: E731
        for attempt in range(6):                 # a first frame may come before its camera info: send again
            for topic, msg in messages:
                pubs[topic].publish(msg)
            try:
                states.wait(1, timeout=20, predicate=answered)
                break
            except TimeoutError:
                continue
        else:
            pytest.fail(f"no /slam/state for the frame at {pair.stamp_s:.3f} s")

    # a floor point fixed in the world where the first camera looks; where the slam poses put it
    got = sorted(((stamp_to_seconds(m.header.stamp), pose_to_matrix(m.pose)) for m in poses.messages),
                 key=lambda x: x[0])
    assert len(got) >= 0.9 * len(recording.pairs), f"{len(got)} poses for {len(recording.pairs)} frames"
    assert all(m.header.frame_id == frames.MAP for m in poses.messages)
    moved, turned = floor_point_moved(got)
    away = int(np.argmax(turned > PAN_DEG))
    assert away > 0 and turned[away:].min() < PAN_DEG / 3, turned.round(0)       # away, and back (≤ 10°)

    # the tf tree reaches the camera from map; the tracking state is in /spv/status
    watch.wait_for({frames.MAP, frames.CAMERA_OPTICAL}, timeout=30)
    assert not watch.unconnected(), (watch.unconnected(), watch.tree.edges())
    last_t, last_T = got[-1]
    assert watch.tree.lookup(frames.MAP, frames.CAMERA_OPTICAL, last_t) == pytest.approx(last_T, abs=1e-6)
    final = json.loads(states.messages[-1].data)["state"]
    assert json.loads(states.messages[-1].data)["map_id"] == 0                    # never lost: the first map
    status.wait(1, timeout=30, predicate=lambda m: json.loads(m.data).get("localisation") == {"source": "slam",
                                                                                              "state": final,
                                                                                              "map_id": 0})

    # saved while running (a killed node loses at most one autosave period), on request, at the stop
    deadline = time.monotonic() + 60
    while not (tmp_path / "map" / "map.yaml").is_file() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert (tmp_path / "map" / "map.yaml").is_file(), "not autosaved"
    from raspv_msgs.srv import SaveMap
    client = probe.node.create_client(SaveMap, topics.SLAM_SAVE_MAP)
    assert client.wait_for_service(timeout_sec=30)
    answer = client.call_async(SaveMap.Request(path=str(tmp_path / "asked")))
    deadline = time.monotonic() + 60
    while not answer.done() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert answer.done() and answer.result().success and answer.result().keyframes >= 1, answer.result()
    assert (tmp_path / "asked" / "map.yaml").is_file()
    assert g.stop() == 0
    assert "map saved to" in g.output
    from raspv_slam.map_store import check_map
    check_map(str(tmp_path / "map"))
    # the issue's target, with fr1's 25-ms readout: 4.8 cm at most, 4.5 at the return in every run (docs/slam.md)
    print(f"floor point in the map: moved {moved.max():.3f} m at most, {moved[-1]:.3f} m at the return "
          f"({moved.round(3).tolist()})")
    assert moved.max() <= FLOOR_TOLERANCE_M, (f"floor point moved {moved.max():.3f} m in the map at most, "
                                              f"{moved[-1]:.3f} m at the return ({moved.round(3).tolist()})")
