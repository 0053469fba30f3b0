"""The spv node starts as a normal process and takes real-time priority only once its display
shows a frame computed from inputs (issue 36): a replacement spv whose start-up (node, first depth
frame) ran at real-time priority held the bridge's frame thread up ~0.36 s after a ``kill -9``.
The real spv node; depth and camera info published by the test."""
from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo, Image

from raspv_common import topics
from raspv_common.conversions import array_to_image, intrinsics_to_camera_info
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import SENSOR_QOS
from raspv_common.thread_priority import DISPLAY_RT_PRIORITY, HEADSET_RT_PRIORITY
from raspv_msgs.msg import PhospheneFrame
from raspv_spv.staleness import NO_DATA

pytestmark = pytest.mark.integration

K = CameraIntrinsics.from_hfov(160, 120, 70.0)


def _policies(pid: int) -> list[tuple[int, int]]:
    """(scheduling class, real-time priority) of each thread of ``pid``."""
    out = []
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            out.append((os.sched_getscheduler(int(tid)) & 0xFF, os.sched_getparam(int(tid)).sched_priority))
        except OSError:                               # the thread ended meanwhile
            pass
    return out


def _realtime_allowed() -> bool:
    seen = []

    def probe_rt():
        try:
            os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(1))
            seen.append(True)
        except (AttributeError, OSError):
            seen.append(False)

    t = threading.Thread(target=probe_rt)       # a thread of its own: the test process stays normal
    t.start()
    t.join()
    return seen[0]


@pytest.mark.skipif(not _realtime_allowed(), reason="no permission for real-time scheduling here")
def test_spv_runs_at_normal_priority_until_its_display_shows_a_frame_from_inputs(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "spv"}]},
               "spv": {"ros__parameters": {"mode": "depth", "width": 160, "rate": 25.0, "temporal": False,
                                           "reprojection": False}}})
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    frames.wait(3, timeout=60)                                    # its display runs: the no-data pattern
    assert all(f.mode == NO_DATA for f in frames.messages)
    pid = g.pid_of("spv")
    before = _policies(pid)
    assert len(before) > 3 and all(policy == os.SCHED_OTHER for policy, _ in before), before

    depth = probe.publisher(topics.DEPTH, Image, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
    info = probe.publisher(topics.CAMERA_INFO, CameraInfo, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
    stop = threading.Event()

    def publish():
        image = np.full((K.height, K.width), 1.0, np.float32)
        while not stop.wait(0.05):
            stamp = probe.node.get_clock().now().to_msg()
            for pub, msg in ((info, intrinsics_to_camera_info(K)), (depth, array_to_image(image, "32FC1"))):
                msg.header.stamp = stamp
                pub.publish(msg)

    source = threading.Thread(target=publish, daemon=True)
    source.start()
    try:
        frames.wait(1, timeout=60, predicate=lambda f: f.mode == "depth" and max(f.levels) > 0)
        deadline = time.monotonic() + 10.0            # the display thread raises the process after that tick
        while not any(policy == os.SCHED_RR for policy, _ in _policies(pid)):
            assert time.monotonic() < deadline, _policies(pid)
            time.sleep(0.05)
        time.sleep(0.2)                               # (all its threads are raised in one go, right after)
        after = _policies(pid)
        rt = sorted(prio for policy, prio in after if policy == os.SCHED_RR)
        assert rt.count(DISPLAY_RT_PRIORITY) == 1 and rt.count(HEADSET_RT_PRIORITY) >= 3, after
    finally:
        stop.set()
        source.join()
