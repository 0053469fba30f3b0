"""The `bridge` node in real graphs: frames out to a client, head pose and teleop into ROS with the
dead-man, viewer keys changing another node's parameters, one-line errors, and the whole chain
synthetic camera → spv → bridge → client."""
from __future__ import annotations

import asyncio
import json
import re
import socket
import threading
import time

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import QuaternionStamped, Twist
from rcl_interfaces.msg import SetParametersResult
from sensor_msgs.msg import Image
from websockets.asyncio.client import connect

from raspv_common import topics
from raspv_common.conversions import array_to_image
from raspv_common.qos import SENSOR_QOS
from raspv_hmd import protocol as P
from raspv_hmd.reference_client import ClientOptions, HeadScript, parse_endpoint, run_client

pytestmark = pytest.mark.integration

URL = r"open (http://127\.0\.0\.1:(\d+)/) in a browser; native clients: tcp://127\.0\.0\.1:(\d+)"


def start_bridge(graph, **params):
    g = graph({"launch": {"nodes": [{"kind": "bridge"}]},
               "bridge": {"ros__parameters": {"port": 0, "tcp_port": 0, **params}}})
    m = g.wait_for_output(URL, timeout=60)
    return g, m.group(1), int(m.group(3))


async def controller(url: str):
    ws = await connect(parse_endpoint(url).ws_url, max_size=None, compression=None)
    await ws.send(P.client_message("hello", name="test", role="control"))
    welcome = json.loads(await ws.recv())
    assert welcome["role"] == "control"
    return ws


async def next_status(ws, timeout=20.0):
    while True:
        msg = await asyncio.wait_for(ws.recv(), timeout)
        if isinstance(msg, str) and json.loads(msg)["type"] == "status":
            return json.loads(msg)


def test_frames_head_and_teleop_through_the_bridge(graph, probe):
    g, url, tcp_port = start_bridge(graph, max_linear=1.0, deadman_timeout=0.3)
    heads = probe.subscribe(topics.HEAD_ORIENTATION, QuaternionStamped, wait_for_publishers=1, timeout=60)
    twists = probe.subscribe(topics.CMD_VEL, Twist, wait_for_publishers=1, timeout=60)
    image = np.zeros((200, 300), np.uint8)
    image[50:150, 100:200] = 255
    reports = []
    client = threading.Thread(target=lambda: reports.append(asyncio.run(run_client(
        parse_endpoint(f"tcp://127.0.0.1:{tcp_port}"),
        ClientOptions(max_frames=40, duration_s=60, head=HeadScript(period_s=1.0), head_rate_hz=10.0,
                      keep_last_frame=True)))))
    client.start()
    # the bridge subscribes to /spv/image while a client wants images (this raw TCP client)
    pub = probe.publisher(topics.SPV_IMAGE, Image, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
    while client.is_alive():
        msg = array_to_image(image, "mono8")
        msg.header.stamp = probe.node.get_clock().now().to_msg()
        pub.publish(msg)
        time.sleep(0.02)
    client.join()
    [report] = reports
    assert report.frames == 40 and np.array_equal(report.last_frame, image)
    assert max(report.latency_ms) < 10_000 and min(report.latency_ms) > -100   # image stamps carried through
    def rounded(m):
        return tuple(np.round([m.quaternion.x, m.quaternion.y, m.quaternion.z, m.quaternion.w], 6))
    sent = [tuple(np.round(q, 6)) for _, q in report.heads_sent]
    heads.wait(1, timeout=30, predicate=lambda m: rounded(m) == sent[-1])     # the newest head pose arrives
    got = list(heads.messages)
    assert all(m.header.frame_id == "base_link" for m in got)
    # /head/orientation is keep-last-1 (only the newest pose matters), so a loaded machine may skip
    # some (a CI run once delivered 1 of ~10 poses sent 20 ms apart, before the subscription was
    # awaited); what must hold is that only sent poses arrive, as a stream (here ~8 poses 100 ms
    # apart), ending with the newest
    assert {rounded(m) for m in got} <= set(sent) and len(got) >= 2

    refusal = r"ignoring /spv/image in '32FC1'; expected mono8 or rgb8"

    async def drive():
        ws = await controller(url)
        await ws.send(P.client_message("twist", linear=3.0, angular=0.5))     # above max_linear
        twists.wait(2, timeout=30, predicate=lambda t: True)                  # the command, then the stop
        # a wrong encoding on /spv/image, while this client wants images (the bridge subscribes then)
        bad = array_to_image(np.zeros((4, 4), np.float32), "32FC1")
        for _ in range(300):
            pub.publish(bad)
            if re.search(refusal, g.output):
                break
            await asyncio.sleep(0.1)
        await ws.close()
    asyncio.run(drive())
    first, stop = twists.wait(2, timeout=30)
    assert (first.linear.x, first.angular.z) == (1.0, 0.5)                    # clamped
    assert (stop.linear.x, stop.angular.z) == (0.0, 0.0)                      # dead-man
    g.wait_for_output(refusal, timeout=5)
    assert g.running()


class FakeSpv:
    """A node with spv-like parameters in the test process; refuses mode 'nonsense'."""

    def __init__(self, probe, name: str) -> None:
        self.node = rclpy.create_node(name, context=probe.context)
        for pname, default in [("device", "default"), ("num_phosphenes", 0), ("mode", "grey"), ("max_depth", 3.0)]:
            self.node.declare_parameter(pname, default)
        self.node.add_on_set_parameters_callback(
            lambda ps: SetParametersResult(successful=all(p.value != "nonsense" for p in ps),
                                           reason="'nonsense' is not a mode"))
        self.probe = probe
        probe.executor.add_node(self.node)

    def value(self, name):
        return self.node.get_parameter(name).value

    def close(self):
        self.probe.executor.remove_node(self.node)
        self.node.destroy_node()


def test_viewer_keys_change_the_spv_nodes_parameters(graph, probe):
    name = f"fake_spv_{int(time.time() * 1000) % 100000}"
    spv = FakeSpv(probe, name)
    try:
        g, url, _ = start_bridge(graph, spv_node=name, modes=["grey", "depth"])

        async def press():
            ws = await controller(url)
            steps = [("+", "spv num_phosphenes 1000 → 1100", True),     # 0 = the default device's 1000
                     ("+", "spv num_phosphenes 1100 → 1210", True),
                     ("2", "spv mode depth", True),
                     ("J", "spv max_depth 3.0 → 3.5", True),
                     ("3", "key 3: only 2 modes (grey, depth)", False),
                     ("q", "key 'q' does nothing here", False),
                     ("*", "has no parameter 'phosphene_fov_deg'", False)]
            for key, text, ok in steps:
                await ws.send(P.client_message("key", key=key))
                status = await next_status(ws)
                assert text in status["text"] and status["ok"] is ok, (key, status)
            await ws.send(P.client_message("param", name="mode", value="nonsense"))
            status = await next_status(ws)
            assert not status["ok"] and "'nonsense' is not a mode" in status["text"]
            await ws.send(P.client_message("param", name="max_depth", value=2))     # int for a double
            assert (await next_status(ws))["ok"]
            spv.close()
            await ws.send(P.client_message("key", key="+"))
            status = await next_status(ws)
            assert not status["ok"] and re.search("not running or not reachable|did not answer", status["text"])
            await ws.close()
        asyncio.run(press())
        assert spv.value("num_phosphenes") == 1210 and spv.value("mode") == "depth"
        assert spv.value("max_depth") == 2.0
        assert g.running() and "Traceback" not in g.output
    finally:
        if spv.node.handle is not None:
            try:
                spv.close()
            except Exception:
                pass


def test_port_in_use_is_a_one_line_error(graph):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        g = graph({"launch": {"nodes": [{"kind": "bridge"}]},
                   "bridge": {"ros__parameters": {"port": port, "tcp_port": -1}}})
        m = g.wait_for_output(r"\[bridge\] configuration error: (.*)", timeout=60)
        assert f"cannot listen on 127.0.0.1:{port}" in m.group(1) and "in use" in m.group(1)
        g.proc.wait(timeout=30)
        assert g.stop() == 1 and "Traceback" not in g.output


def test_phosphenes_from_the_camera_reach_a_headset_client(graph):
    g = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "spv"}, {"kind": "bridge"}]},
               "cam": {"ros__parameters": {"rate": 20.0, "width": 160, "height": 120}},
               "spv": {"ros__parameters": {"width": 320, "device": "argus_iii", "rate": 25.0}},
               "bridge": {"ros__parameters": {"port": 0, "tcp_port": 0}}})
    url = g.wait_for_output(URL, timeout=60).group(1)
    deadline = time.monotonic() + 90
    while True:                                   # the spv node may still be building its tables
        report = asyncio.run(run_client(parse_endpoint(url), ClientOptions(max_frames=5, duration_s=20,
                                                                           keep_last_frame=True, head=None)))
        if report.frames == 5 and report.last_frame.max() > 0 or time.monotonic() > deadline:
            break
    assert report.frames == 5 and report.size == (320, 192)
    assert report.last_frame.max() > 0          # phosphenes are lit

    async def press():                          # the viewer keys name the real spv node's parameters
        ws = await controller(url)
        for key, text in [("+", "spv num_phosphenes 240 → 264"), ("J", "spv max_depth 3.0 → 3.5"),
                          ("n", "spv noise_px 0.0 → 0.0"), ("2", "spv mode depth")]:
            await ws.send(P.client_message("key", key=key))
            status = await next_status(ws, timeout=60)
            assert status["ok"] and text in status["text"], (key, status)
        await ws.close()
    asyncio.run(press())


def test_navigation_guidance_reaches_the_client_as_audio_cues(graph, probe):
    """/nav/guidance (world) and /odom → a `cues` message in the avatar's base frame."""
    import math

    from nav_msgs.msg import Odometry
    from raspv_msgs.msg import NavGuidance

    from raspv_common.conversions import matrix_to_pose
    from raspv_nav.motion import planar_transform

    g, url, _ = start_bridge(graph)
    guide_pub = probe.publisher(topics.NAV_GUIDANCE, NavGuidance, qos=SENSOR_QOS, wait_for_subscribers=1, timeout=60)
    odom_pub = probe.publisher(topics.ODOM, Odometry, qos=SENSOR_QOS)   # the bridge subscribes once guidance comes

    async def receive_cues():
        ws = await controller(url)
        try:
            while True:
                msg = await asyncio.wait_for(ws.recv(), 30.0)
                if isinstance(msg, str) and json.loads(msg)["type"] == "cues":
                    return json.loads(msg)
        finally:
            await ws.close()

    result = []
    listener = threading.Thread(target=lambda: result.append(asyncio.run(receive_cues())))
    listener.start()
    while listener.is_alive():                    # standing at (1, 2) facing +y; the waypoint at (3, 4)
        stamp = probe.node.get_clock().now().to_msg()
        odom = Odometry()
        odom.header.stamp, odom.header.frame_id = stamp, "odom"
        odom.pose.pose = matrix_to_pose(planar_transform(1.0, 2.0, math.pi / 2))
        odom_pub.publish(odom)
        guide = NavGuidance(has_path=True, has_waypoint=True, feasible=True)
        guide.header.stamp, guide.header.frame_id = stamp, "map"
        guide.next_waypoint.x, guide.next_waypoint.y = 3.0, 4.0
        guide_pub.publish(guide)
        time.sleep(0.05)
    listener.join()
    [cues] = result
    assert cues["frame"] == "base" and cues["has_path"]
    assert cues["waypoint"]["position"] == pytest.approx([2.0, -2.0, 0.0], abs=1e-3)   # 2 m ahead, 2 m right
    assert cues["obstacle"] is None and cues["stairs"] is None
