"""The spv node's carry_scene: a new depth frame is shown at once with the newest scene labels
carried into it (scene_stamp says which), then again with its own labels; with carry_scene off it
waits for them. Inputs published by the test, the real spv node."""
import time

import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo, Image

from raspv_common import topics
from raspv_common.conversions import array_to_image, intrinsics_to_camera_info, seconds_to_stamp, stamp_to_seconds
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import SENSOR_QOS
from raspv_msgs.msg import PhospheneFrame
from raspv_perception import scene_labels as L

pytestmark = pytest.mark.integration

K = CameraIntrinsics.from_hfov(160, 120, 70.0)
FULL, HALF = 7, 4                     # the optimist preset's 8 levels: obstacles full, walls half


def test_a_depth_frame_is_shown_with_the_scene_carried_into_it_then_with_its_own(graph, probe):
    graph({"launch": {"nodes": [{"kind": "spv"}]},
           "spv": {"ros__parameters": {"device": "optimist", "mode": "wall_obstacles", "width": 160, "rate": 20.0,
                                       "temporal": False, "reprojection": False, "stale_inputs": False}}})
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    pubs = {name: probe.publisher(topic, kind, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
            for name, topic, kind in (("info", topics.CAMERA_INFO, CameraInfo), ("depth", topics.DEPTH, Image),
                                      ("labels", topics.SCENE_LABELS, Image))}
    depth = np.full((K.height, K.width), 1.0, np.float32)
    t0 = stamp_to_seconds(probe.node.get_clock().now().to_msg())

    def publish(name, t, label=None):
        msg = {"info": lambda: intrinsics_to_camera_info(K), "depth": lambda: array_to_image(depth, "32FC1"),
               "labels": lambda: array_to_image(np.full(depth.shape, label, np.uint8), "mono8")}[name]()
        msg.header.stamp = seconds_to_stamp(t)
        pubs[name].publish(msg)

    def shown(t, scene_t, *messages):
        """The first frame of source ``t`` from the scene result of ``scene_t``; ``messages``
        ((name, stamp, label)) are published again every 0.5 s until it comes (a sensor-QoS
        message can be lost while discovery completes on a loaded machine)."""
        deadline = time.monotonic() + 30
        while True:
            for m in messages:
                publish(*m)
            try:
                return frames.wait(1, timeout=0.5, predicate=lambda f: abs(stamp_to_seconds(f.source_stamp) - t) < 1e-6
                                   and abs(stamp_to_seconds(f.scene_stamp) - scene_t) < 1e-6)[0]
            except TimeoutError:
                if time.monotonic() > deadline:
                    raise

    try:
        # frame 1 with its labels: obstacles everywhere
        assert set(shown(t0, t0, ("info", t0), ("depth", t0), ("labels", t0, L.OBSTACLE)).levels) == {FULL}
        # frame 2's depth alone: shown at once with frame 1's labels carried into it
        t1 = t0 + 0.05
        carried = shown(t1, t0, ("info", t1), ("depth", t1))
        assert set(carried.levels) == {FULL} and carried.mode == "wall_obstacles"
        # frame 2's own labels (walls): shown again with them
        assert set(shown(t1, t1, ("labels", t1, L.WALL)).levels) == {HALF}

        # carry_scene off: frame 3's depth waits for its labels
        [(_, ok, _)] = probe.set_params("spv", {"carry_scene": False})
        assert ok
        t2 = t1 + 0.05
        publish("info", t2)
        publish("depth", t2)
        ticks = len(frames.messages)
        frames.wait(ticks + 5, timeout=30)            # five display ticks (0.25 s) with the depth in
        assert set(shown(t2, t2, ("info", t2), ("depth", t2), ("labels", t2, L.OBSTACLE)).levels) == {FULL}
        of_frame_3 = [f for f in frames.messages if abs(stamp_to_seconds(f.source_stamp) - t2) < 1e-6]
        assert all(abs(stamp_to_seconds(f.scene_stamp) - t2) < 1e-6 for f in of_frame_3)
    finally:
        probe.unsubscribe(frames)
