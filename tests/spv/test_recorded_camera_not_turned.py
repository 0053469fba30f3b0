"""config/camera.yaml replaying a recording: dragging in the browser client (the bridge
publishing /head/orientation; here the probe publishes it as the bridge would) does not move
the phosphenes — the launcher sets spv's camera_source to 'recording' (raspv_spv.camera_source).
As a control, the same drag turns them once the node is told the camera is on the head."""
import math
import time

import numpy as np
import pytest
from geometry_msgs.msg import QuaternionStamped

from raspv_camera.sdk_recordings import SourceFrame, write_realsense_recording
from raspv_common import topics
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import COMMAND_QOS
from raspv_msgs.msg import PhospheneFrame

pytestmark = [pytest.mark.integration, pytest.mark.slow]

K = CameraIntrinsics(160, 120, 140.0, 140.0, 79.5, 59.5)


def still_recording(path):
    """One still scene recorded for 1 s: a horizontal colour ramp (any turn changes the grey levels)."""
    u = np.linspace(0, 255, K.width).astype(np.uint8)
    color = np.repeat(np.broadcast_to(u, (K.height, K.width))[..., None], 3, axis=2).copy()
    depth = np.full((K.height, K.width), 1500, np.uint16)
    frames = [SourceFrame(color, depth, 10.0 + i / 30, np.array([0.0, -9.8, 0.0])) for i in range(30)]
    return write_realsense_recording(path, frames, K, with_accel=True)


def spv_reads_the_head(probe) -> bool:
    return any(i.node_name == "spv" for i in probe.node.get_subscriptions_info_by_topic(topics.HEAD_ORIENTATION))


def head_msg(probe, yaw_deg):
    m = QuaternionStamped()
    m.header.stamp = probe.node.get_clock().now().to_msg()
    m.header.frame_id = "base_link"
    m.quaternion.z, m.quaternion.w = math.sin(math.radians(yaw_deg) / 2), math.cos(math.radians(yaw_deg) / 2)
    return m


def levels_while_dragging(probe, head, yaws_deg):
    """Levels of every phosphene frame published while the head is dragged through ``yaws_deg``
    (one step per phosphene frame: ~100°/s with 2° steps at 50 Hz — between two camera frames the
    view of a camera on the head turns, which display-time reprojection shows)."""
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    try:
        for yaw in yaws_deg:
            head.publish(head_msg(probe, float(yaw)))
            frames.wait(len(frames.messages) + 1, timeout=30)
        shown = list(frames.messages)
        assert {m.mode for m in shown} == {"grey"}, f"the display left its mode: {[m.mode for m in shown]}"
        return [bytes(m.levels) for m in shown]
    finally:
        probe.unsubscribe(frames)


STILL = [0.0] * 15
DRAG = list(np.arange(0.0, 40.0, 2.0)) + list(np.arange(40.0, 0.0, -2.0))


def test_dragging_does_not_turn_a_recorded_camera(graph, probe, tmp_path):
    rec = still_recording(tmp_path / "still.db3")
    graph("config/camera.yaml", [f"camera.file:={rec}", "spv.mode:=grey", "spv.temporal:=false", "spv.width:=200",
                                 "bridge.port:=0", "bridge.tcp_port:=-1"])
    # until the camera's first frame the display shows the no-data ring: wait for the mode itself
    probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=90, predicate=lambda f: f.mode == "grey")
    assert probe.get_params("spv", ["camera_source"]) == {"camera_source": "recording"}
    head = probe.publisher(topics.HEAD_ORIENTATION, QuaternionStamped, qos=COMMAND_QOS)
    assert not spv_reads_the_head(probe)
    ahead = levels_while_dragging(probe, head, STILL)
    assert len(set(ahead)) == 1, "a still recording shows still phosphenes"
    dragged = levels_while_dragging(probe, head, DRAG)
    assert set(dragged) == set(ahead), "dragging moved the phosphenes of a recorded camera"
    # control: were the camera on the viewer's head, the same drag would move them
    [(_, ok, reason)] = probe.set_params("spv", {"camera_source": "head"})
    assert ok, reason
    deadline = time.monotonic() + 30
    while not spv_reads_the_head(probe):
        assert time.monotonic() < deadline, "spv did not subscribe to /head/orientation"
        time.sleep(0.05)
    levels_while_dragging(probe, head, STILL)
    turned = levels_while_dragging(probe, head, DRAG)
    assert set(turned) - set(ahead)
