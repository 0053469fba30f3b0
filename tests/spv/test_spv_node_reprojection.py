"""The spv node's display loop: the last frame turned to the newest /head/orientation between camera
frames (display-time reprojection), switched off by a parameter, and shown after a simulated
device latency — one frame published by the test, no simulator."""
import json
import math
import time

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped, QuaternionStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import String

from raspv_common import topics
from raspv_common.conversions import array_to_image, intrinsics_to_camera_info, matrix_to_pose, stamp_to_seconds
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import COMMAND_QOS, LATCHED_QOS, SENSOR_QOS
from raspv_msgs.msg import PhospheneFrame
from raspv_spv.reprojection import OPTICAL_IN_HEAD
from raspv_bringup.testing import RunningGraph

pytestmark = pytest.mark.integration

K = CameraIntrinsics.from_hfov(320, 240, 80.0)


def ramp() -> np.ndarray:
    u = np.linspace(0, 255, K.width, dtype=np.float32)
    return np.repeat(np.broadcast_to(u, (K.height, K.width))[..., None], 3, axis=2).astype(np.uint8)


def head_msg(probe, yaw_deg: float) -> QuaternionStamped:
    m = QuaternionStamped()
    m.header.stamp = probe.node.get_clock().now().to_msg()
    m.header.frame_id = "base_link"
    m.quaternion.z, m.quaternion.w = math.sin(math.radians(yaw_deg) / 2), math.cos(math.radians(yaw_deg) / 2)
    return m


class Source:
    """Publishes one camera frame (colour, info, camera pose, odometry) with a given stamp."""

    def __init__(self, probe) -> None:
        self.probe = probe
        self.color = probe.publisher(topics.COLOR, Image, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
        self.info = probe.publisher(topics.CAMERA_INFO, CameraInfo, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
        self.pose = probe.publisher(topics.CAMERA_POSE, PoseStamped, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
        self.odom = probe.publisher(topics.ODOM, Odometry, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
        self.head = probe.publisher(topics.HEAD_ORIENTATION, QuaternionStamped, qos=COMMAND_QOS,
                                    wait_for_subscribers=1, timeout=60)

    def frame(self) -> float:
        stamp = self.probe.node.get_clock().now().to_msg()
        img = array_to_image(ramp(), "rgb8")
        img.header.stamp = stamp
        info = intrinsics_to_camera_info(K)
        info.header.stamp = stamp
        T = np.eye(4)                               # base at the origin, head straight: camera = optical axes
        T[:3, :3] = OPTICAL_IN_HEAD
        T[:3, 3] = (0.08, 0.0, 1.6)
        pose = PoseStamped(pose=matrix_to_pose(T))
        pose.header.stamp, pose.header.frame_id = stamp, "map"
        odom = Odometry(child_frame_id="base_link")
        odom.header.stamp, odom.header.frame_id = stamp, "odom"
        odom.pose.pose.orientation.w = 1.0
        self.info.publish(info)
        self.color.publish(img)
        self.pose.publish(pose)
        self.odom.publish(odom)
        return stamp_to_seconds(stamp)


def test_display_turns_the_last_frame_with_the_head_and_waits_the_device_latency(graph, probe):
    graph({"launch": {"nodes": [{"kind": "spv"}]},
           # one camera frame held for seconds on purpose: not a camera that stopped
           "spv": {"ros__parameters": {"device": "optimist", "width": 200, "mode": "grey", "temporal": False,
                                       "rate": 25.0, "stale_inputs": False,
                                       "camera_source": "sim"}}})
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    src = Source(probe)
    src.head.publish(head_msg(probe, 0.0))

    def of(stamp):
        return lambda f: abs(stamp_to_seconds(f.source_stamp) - stamp) < 1e-6 and max(f.levels) > 0
    t0, still = _first_frame(src, frames, of)
    # the head turns 15° left; no new camera frame: the display re-samples the one it has
    turn = head_msg(probe, 15.0)
    src.head.publish(turn)
    t_turn = stamp_to_seconds(turn.header.stamp)
    turned = frames.wait(1, timeout=30, predicate=lambda f: of(t0)(f) and stamp_to_seconds(f.header.stamp) > t_turn
                         and np.mean(np.array(f.levels) != still) > 0.3)[0]
    assert stamp_to_seconds(turned.source_stamp) == pytest.approx(t0)
    # looking left on a left-dark ramp: the phosphenes still inside the image got darker
    lv = np.array(turned.levels, dtype=int)
    both = (lv > 0) & (still > 0)
    assert both.sum() > 50 and (lv[both] <= still[both]).all()

    # reprojection off: the frame as captured again, whatever the head does
    [(_, ok, _)] = probe.set_params("spv", {"reprojection": False})
    assert ok
    t_set = time.time()
    frames.wait(1, timeout=30, predicate=lambda f: stamp_to_seconds(f.header.stamp) > t_set and of(t0)(f)
                and np.array_equal(np.array(f.levels), still))

    # a device with 300 ms between capture and display: a new frame is shown 300 ms after its stamp
    [(_, ok, _)] = probe.set_params("spv", {"device_latency_ms": 300.0})
    assert ok
    # (once the frame shown now is older than that: a younger one is not shown yet, the display is dark)
    frames.wait(1, timeout=30, predicate=lambda f: of(t0)(f) and stamp_to_seconds(f.header.stamp) > t0 + 0.35)
    t1 = src.frame()
    first = frames.wait(1, timeout=30, predicate=of(t1))[0]
    assert stamp_to_seconds(first.header.stamp) >= t1 + 0.3 - 1e-3
    # … and meanwhile the display kept showing the frame before it
    shown_between = [f for f in frames.messages if t1 < stamp_to_seconds(f.header.stamp) < t1 + 0.28]
    sources = [round(stamp_to_seconds(f.source_stamp) - t0, 3) for f in shown_between]
    assert shown_between and all(abs(s) < 1e-6 for s in sources), (sources, round(t1 - t0, 3))


def _first_frame(src, frames, of):
    for _ in range(60):            # the first frame may overtake the camera info: send until one is shown
        t0 = src.frame()
        try:
            return t0, np.array(frames.wait(1, timeout=1.0, predicate=of(t0))[0].levels)
        except TimeoutError:
            continue
    pytest.fail("the spv node never showed a frame")


@pytest.fixture(scope="module")
def one_hz_display(tmp_path_factory, ros_domain):
    """An spv node with a 1 Hz display (waiting for the tick would take up to a second), started
    once for the three cases below; each sets its temporal model and display_on_input at run time."""
    g = RunningGraph({"launch": {"nodes": [{"kind": "spv"}]},
                      "spv": {"ros__parameters": {"device": "optimist", "width": 200, "mode": "grey", "temporal": False,
                                                  "temporal_update": "recursive", "rate": 1.0, "stale_inputs": False,
                                                  "display_on_input": True, "camera_source": "sim"}}},
                     tmp_path_factory.mktemp("one_hz_display"))
    yield g
    code = g.stop()
    assert code == 0, f"the spv graph ended with exit code {code}:\n{g.output[-3000:]}"


@pytest.mark.parametrize("temporal, follow", [(False, True), (False, False), ("recursive", True)],
                         ids=["model off", "model off, not following", "recursive model"])
def test_a_head_turn_is_shown_at_once_not_at_the_next_tick(one_hz_display, probe, temporal, follow):
    # The recursive temporal model is advanced by the real time of each frame: the display follows
    # its input with it on too
    results = probe.set_params("spv", {"temporal": bool(temporal), "temporal_update": temporal or "recursive",
                                       "display_on_input": follow})
    assert all(ok for _, ok, _ in results), results
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    src = Source(probe)
    src.head.publish(head_msg(probe, 0.0))

    def of(stamp):                  # (a frame of the simulator with this case's model: rebuilt in the background)
        return lambda f: (abs(stamp_to_seconds(f.source_stamp) - stamp) < 1e-6 and max(f.levels) > 0
                          and f.temporal == bool(temporal))
    t0, still = _first_frame(src, frames, of)
    delays = []
    for yaw in (15.0, 0.0, 15.0):
        # just after a tick: the next regular one is ~1 s away
        before = len(frames.messages)
        frames.wait(before + 1, timeout=30)
        turn = head_msg(probe, yaw)
        src.head.publish(turn)
        t_turn = stamp_to_seconds(turn.header.stamp)
        shown = frames.wait(1, timeout=30, predicate=lambda f: stamp_to_seconds(f.header.stamp) > t_turn)[0]
        delays.append(stamp_to_seconds(shown.header.stamp) - t_turn)
    if follow:
        # at once (at most a quarter period after the previous frame), not up to a second later
        assert max(delays) < 0.5, delays
    else:
        assert max(delays) > 0.5, delays            # the tick it waited for
    if temporal == "recursive":         # /spv/status says what the rate and the headset rates cost here
        status = probe.wait_for_message(topics.SPV_STATUS, String, timeout=30, qos=LATCHED_QOS,
                                        predicate=lambda m: "display" in json.loads(m.data))
        display = json.loads(status.data)["display"]
        assert display["rate_hz"] == 1.0 and display["verdict"] == "ok"
        assert set(display["rates"]) == {"50", "72", "90", "120"} and display["rates"]["90"]["frame_ms"] > 0
