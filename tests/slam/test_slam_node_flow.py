"""The `slam` node gives the frames its `max_rate` leaves out a pose too (optical flow from the last
tracked frame, raspv_slam.flow_tracking), on real frames: TUM fr1/rpy at 15 Hz
(tests/data/tum_fr1_rpy_subset) into a node at 10 Hz, so every other frame is one the core skips.
Those poses agree with the mocap's motion from the frame before; before, they had none and the
display guessed them at constant velocity.

The test is the source: each frame is sent once the node answered the one before (a pose for it,
or its /slam/state), so every frame is looked at whatever the machine's load."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header, String

from raspv_bags.from_frames import CAMERA_DISTORTION, CAMERA_PRESETS, discover_frames, read_depth
from raspv_common import frames, topics
from raspv_common.conversions import array_to_image, intrinsics_to_camera_info, pose_to_matrix, seconds_to_stamp, \
    stamp_to_seconds
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import LATCHED_QOS, SENSOR_QOS
from raspv_common.rgbd_files import read_color
from tests.slam.conftest import motion_error
from tests.slam.pan_floor import ground_truth

pytestmark = [pytest.mark.integration]

DATA = Path(__file__).resolve().parents[1] / "data" / "tum_fr1_rpy_subset"



def test_frames_between_the_cores_get_poses_that_follow_the_camera(graph, probe):
    recording = discover_frames(DATA)
    K = CameraIntrinsics(640, 480, *CAMERA_PRESETS["tum-fr1"])
    truth = ground_truth(DATA)
    poses = probe.subscribe(topics.CAMERA_POSE, PoseStamped)
    states = probe.subscribe(topics.SLAM_STATE, String, qos=LATCHED_QOS)
    graph({"launch": {"nodes": [{"kind": "slam"}]},
           "slam": {"ros__parameters": {"gravity_from_floor": False, "save_on_exit": False, "autosave_period": 0.0,
                                        "max_rate": 10.0}}})
    pubs = {t: probe.publisher(t, cls, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=120)
            for t, cls in ((topics.CAMERA_INFO, CameraInfo), (topics.COLOR, Image), (topics.DEPTH, Image))}
    pairs = recording.pairs[:40]
    for pair in pairs:
        header = Header(stamp=seconds_to_stamp(pair.stamp_s), frame_id=frames.CAMERA_OPTICAL)
        messages = [(topics.CAMERA_INFO, intrinsics_to_camera_info(K, header, CAMERA_DISTORTION["tum-fr1"])),
                    (topics.COLOR, array_to_image(read_color(pair.color), "rgb8", header)),
                    (topics.DEPTH, array_to_image(read_depth(pair.depth, recording.depth_format,
                                                             recording.depth_scale), "32FC1", header))]
        stamp = pair.stamp_s
        posed = lambda m, t=stamp: abs(stamp_to_seconds(m.header.stamp) - t) < 1e-3            # noqa: E731
        stated = lambda m, t=stamp: abs(json.loads(m.data)["stamp"] - t) < 1e-3                 # noqa: E731
        for attempt in range(6):                 # the first frame may come before its camera info: send again
            for topic, msg in messages:
                pubs[topic].publish(msg)
            try:                                 # a pose (tracked or flow), or the core's state (lost, first frame)
                poses.wait(1, timeout=5 if attempt else 20, predicate=posed)
                break
            except TimeoutError:
                if any(stated(m) for m in states.messages):
                    break
        else:
            pytest.fail(f"no answer for the frame at {stamp:.3f} s")

    # the core's frames: those max_rate lets through (>= 95 ms after the last one taken), as the node decides
    processed, last = set(), None
    for p in pairs:
        if last is None or p.stamp_s - last >= 0.095:
            processed.add(round(p.stamp_s, 3))
            last = p.stamp_s
    got = {round(stamp_to_seconds(m.header.stamp), 3): pose_to_matrix(m.pose) for m in poses.messages}
    between = [round(p.stamp_s, 3) for p in pairs if round(p.stamp_s, 3) not in processed]
    assert len(between) >= 0.4 * len(pairs), f"{len(between)} of {len(pairs)} frames skipped by max_rate"
    flow_posed = [t for t in between if t in got]
    assert len(flow_posed) >= 0.9 * len(between), f"{len(flow_posed)} of the {len(between)} frames between have a pose"
    final = json.loads(states.wait(1, timeout=30, predicate=lambda m: abs(json.loads(m.data)["stamp"]
                                                                             - max(processed)) < 1e-3)[-1].data)
    assert final["flow_frames"] >= len([t for t in flow_posed if t < max(processed)])

    # each such pose against the tracked frame before it: the mocap's motion over those 67 ms
    errors = []
    for t in flow_posed:
        before = max((s for s in processed if s < t and s in got), default=None)
        if before is None:                   # the first frames, before the core placed one
            continue
        est = np.linalg.inv(got[before]) @ got[t]
        true = np.linalg.inv(truth.lookup(before)) @ truth.lookup(t)
        errors.append(motion_error(np.eye(4), np.linalg.inv(est) @ true)[1])
    assert len(errors) >= 0.8 * len(flow_posed)
    print(f"{len(flow_posed)}/{len(between)} frames between posed; rotation vs mocap median "
          f"{np.median(errors):.2f} deg, max {max(errors):.2f}")
    assert np.median(errors) < 1.0 and np.percentile(errors, 90) < 2.5
