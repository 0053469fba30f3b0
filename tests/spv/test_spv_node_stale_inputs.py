"""The spv node when its inputs stop (issue 16): the scene node's labels stop → the depth fallback on
new camera frames; the camera stops → the blinking no-data ring, never the last frame; both come
back → the normal mode at once. Inputs published by the test at 20 Hz, the real spv node."""
import json
import threading
import time

import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import String

from raspv_common import topics
from raspv_common.conversions import array_to_image, intrinsics_to_camera_info, stamp_to_seconds
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import LATCHED_QOS, SENSOR_QOS
from raspv_msgs.msg import PhospheneFrame
from raspv_perception import scene_labels as L
from raspv_spv.staleness import NO_DATA

pytestmark = pytest.mark.integration

K = CameraIntrinsics.from_hfov(160, 120, 70.0)
PERIOD_S = 0.05
STALE_TARGET_S = 0.3     # README: a stale input is shown within 300 ms of its last message
STALE_MARGIN_S = 0.2     # scheduling on a loaded 2-core machine (probe and spv threads scheduled late)


class Source(threading.Thread):
    """Camera (depth + info) and, while ``labels_on``, scene labels of the same stamp, at 20 Hz
    while ``camera_on``; ``last`` is the wall time of the newest message of each."""

    def __init__(self, probe) -> None:
        super().__init__(daemon=True)
        self.probe = probe
        self.depth = probe.publisher(topics.DEPTH, Image, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
        self.info = probe.publisher(topics.CAMERA_INFO, CameraInfo, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
        self.labels = probe.publisher(topics.SCENE_LABELS, Image, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
        self.camera_on = self.labels_on = True
        self.stop = threading.Event()
        self.last = {"camera": 0.0, "labels": 0.0}

    def run(self) -> None:
        depth = np.full((K.height, K.width), 1.0, np.float32)
        labels = np.full((K.height, K.width), L.OBSTACLE, np.uint8)
        while not self.stop.wait(PERIOD_S):
            if not self.camera_on:
                continue
            stamp = self.probe.node.get_clock().now().to_msg()
            for pub, msg in ((self.info, intrinsics_to_camera_info(K)), (self.depth, array_to_image(depth, "32FC1")),
                             *(((self.labels, array_to_image(labels, "mono8")),) if self.labels_on else ())):
                msg.header.stamp = stamp
                pub.publish(msg)
            self.last["camera"] = stamp_to_seconds(stamp)
            if self.labels_on:
                self.last["labels"] = self.last["camera"]


def after(t: float):
    return lambda f: stamp_to_seconds(f.header.stamp) > t


def test_stale_scene_falls_back_to_depth_stale_camera_shows_the_no_data_ring_and_both_recover(graph, probe):
    graph({"launch": {"nodes": [{"kind": "spv"}]},
           "spv": {"ros__parameters": {"device": "optimist", "mode": "wall_obstacles", "width": 160, "rate": 25.0,
                                       "temporal": False, "reprojection": False}}})
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    status = probe.subscribe(topics.SPV_STATUS, String, qos=LATCHED_QOS)
    src = Source(probe)
    src.start()
    try:
        normal = frames.wait(1, timeout=60, predicate=lambda f: f.mode == "wall_obstacles" and max(f.levels) > 0)[0]
        assert set(normal.levels) == {7}                                   # every phosphene on an obstacle
        # steady: the node has learnt the inputs' periods (until then it allows 0.5 s)
        frames.wait(1, timeout=30, predicate=lambda f: f.mode == "wall_obstacles"
                    and stamp_to_seconds(f.source_stamp) > stamp_to_seconds(normal.source_stamp) + 1.0)

        # the scene node stops: depth frames (new ones, not the last scene frame) in the fallback mode
        src.labels_on = False
        t_stop = time.time()
        fallback = frames.wait(3, timeout=30, predicate=lambda f: after(t_stop)(f) and f.mode == "depth")
        detected = stamp_to_seconds(fallback[0].header.stamp) - src.last["labels"]
        assert len({stamp_to_seconds(f.source_stamp) for f in fallback}) > 1 or \
            stamp_to_seconds(fallback[0].source_stamp) > src.last["labels"]
        assert all(0 < max(f.levels) < 7 for f in fallback)                # depth 1 m of 3 m: not full
        s = status.wait(1, timeout=10, predicate=lambda m: json.loads(m.data)["showing"] == "depth")[0]
        assert json.loads(s.data)["stale"] == ["scene_labels"] and json.loads(s.data)["mode"] == "wall_obstacles"

        # back: the normal mode at once
        src.labels_on = True
        t_back = time.time()
        frames.wait(1, timeout=30, predicate=lambda f: after(t_back)(f) and f.mode == "wall_obstacles"
                    and stamp_to_seconds(f.source_stamp) > t_back)

        # the camera stops: the no-data ring (source stamp 0: not the last frame), blinking
        src.camera_on = False
        t_stop = time.time()
        ring = frames.wait(1, timeout=30, predicate=lambda f: after(t_stop)(f) and f.mode == NO_DATA)[0]
        no_data = stamp_to_seconds(ring.header.stamp) - src.last["camera"]
        t_ring = stamp_to_seconds(ring.header.stamp)
        both = frames.wait(2, timeout=10, predicate=lambda f: stamp_to_seconds(f.header.stamp) >= t_ring
                           and f.mode == NO_DATA and stamp_to_seconds(f.source_stamp) == 0.0)
        seen = {max(f.levels) for f in frames.messages if stamp_to_seconds(f.header.stamp) >= t_ring}
        deadline = time.monotonic() + 10
        while seen != {0, 7} and time.monotonic() < deadline:                # on and off phases
            time.sleep(0.05)
            seen = {max(f.levels) for f in frames.messages
                    if stamp_to_seconds(f.header.stamp) >= t_ring and f.mode == NO_DATA}
        assert seen == {0, 7} and both
        lit = np.array([f for f in frames.messages if f.mode == NO_DATA and max(f.levels)][-1].levels) > 0
        assert 0.05 < lit.mean() < 0.3                                       # a sparse ring, not a scene

        # the camera is back: the scene mode again
        src.camera_on = True
        t_back = time.time()
        frames.wait(1, timeout=30, predicate=lambda f: after(t_back)(f) and f.mode == "wall_obstacles"
                    and stamp_to_seconds(f.source_stamp) > t_back)
        print(f"stale scene shown after {detected * 1e3:.0f} ms, stale camera after {no_data * 1e3:.0f} ms "
              "(from the last message; target 300 ms)")
        # the README's 300 ms, with the margin a loaded 2-core machine needs (the probe's publisher
        # thread and the spv node's display thread each scheduled late by up to ~0.1 s)
        assert detected < STALE_TARGET_S + STALE_MARGIN_S and no_data < STALE_TARGET_S + STALE_MARGIN_S
    finally:
        src.stop.set()
        src.join(timeout=5)
        probe.unsubscribe(frames)
        probe.unsubscribe(status)
