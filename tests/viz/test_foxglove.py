"""The `foxglove` node seen from a Foxglove WebSocket client (websockets, raspv_viz/foxglove_client.py):
channels with ros2msg schemas, CDR payloads that decode — with rclpy and with nothing but the
advertised schema (rosbags) — into what the graph published, subscriptions only while a client
watches, parameters read and set through the node's own services, and the token gate."""
from __future__ import annotations

import re

import numpy as np
import pytest

from raspv_common.extras import installed, installed_extras

if not installed("foxglove"):   # the foxglove extra; make test (dev) installs it: there its tests must run
    if "dev" in (installed_extras() or ()):
        pytest.fail("foxglove-sdk (the foxglove extra) is missing from a dev install: make install EXTRAS=dev",
                    pytrace=False)
    pytest.skip("the foxglove extra (requirements/foxglove.txt) is not installed", allow_module_level=True)
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import Image, PointCloud2
from visualization_msgs.msg import MarkerArray
from websockets.exceptions import InvalidStatus

from raspv_bags.message_types import _types_from_concatenated_msg
from raspv_common import topics
from raspv_msgs.msg import PhospheneFrame, SceneStructure
from raspv_viz.foxglove_client import FoxgloveClient
from raspv_viz.foxglove_server import FoxgloveServer, ServerConfig, ros2msg_schema

URL = r"Foxglove: open connection → Foxglove WebSocket → (ws://\S+)"
WATCHED = {topics.SPV_IMAGE: Image, topics.SCENE_STRUCTURE: SceneStructure, topics.VIZ_SCENE: MarkerArray}


def decode_with_schema(channel: dict, payload: bytes):
    """Decode a payload with only what the channel advertised (what the Foxglove app does)."""
    store = get_typestore(Stores.EMPTY)
    store.register(_types_from_concatenated_msg(channel["schema"], channel["schemaName"]))
    return store.deserialize_cdr(payload, channel["schemaName"])


@pytest.mark.integration
@pytest.mark.slow
def test_foxglove_client_sees_the_graph_and_sets_a_parameter(graph, probe):
    g = graph({"launch": {"nodes": ["synthetic", "scene", "spv", "viz", "foxglove"]},
               "synthetic": {"ros__parameters": {"rate": 10.0}},
               "spv": {"ros__parameters": {"mode": "chess_floor"}},
               "foxglove": {"ros__parameters": {"port": 0}}})
    url = g.wait_for_output(URL, timeout=90).group(1)
    published = {topic: probe.subscribe(topic, cls) for topic, cls in WATCHED.items()}
    with FoxgloveClient(url) as client:
        channels = client.wait_for_channels([*WATCHED, topics.SPV_MAP, "/raspv/latency"], timeout=90)
        for topic, cls in WATCHED.items():
            ch = channels[topic]
            assert ch["encoding"] == "cdr" and ch["schemaEncoding"] == "ros2msg"
            assert ch["schemaName"] == cls.__module__.split(".")[0] + "/msg/" + cls.__name__
        assert "MSG: raspv_msgs/Plane" in channels[topics.SCENE_STRUCTURE]["schema"]
        # nobody watches yet: the node takes none of these topics
        assert not _foxglove_subscribes(probe, topics.SPV_IMAGE)

        client.subscribe(list(WATCHED))
        for topic, cls in WATCHED.items():
            got, msg, same = matching(client, published[topic], topic, cls)
            assert same_values(same, msg), topic       # (CDR padding bytes are not defined: compare values)
            foreign = decode_with_schema(channels[topic], got.payload)
            if cls is Image:
                assert (foreign.width, foreign.height, foreign.encoding) == (msg.width, msg.height, msg.encoding)
                np.testing.assert_array_equal(foreign.data, np.frombuffer(bytes(msg.data), np.uint8))
            elif cls is SceneStructure:
                assert len(foreign.planes) == len(msg.planes) and foreign.floor_found == msg.floor_found
                np.testing.assert_array_equal([[q.x, q.y, q.z] for q in foreign.planes[0].hull],
                                              [[q.x, q.y, q.z] for q in msg.planes[0].hull])
            else:
                assert [m.ns for m in foreign.markers] == [m.ns for m in msg.markers]
        assert _foxglove_subscribes(probe, topics.SPV_IMAGE)

        # the viz node's cloud and phosphenes, in the world frame (the synthetic source has a pose)
        # (coloured when the colour image of the same stamp had arrived: on a loaded machine the
        # depth frame's may come first, and that cloud is published without colour)
        cloud = probe.wait_for_message(topics.VIZ_CLOUD, PointCloud2, timeout=60,
                                       predicate=lambda c: [f.name for f in c.fields][-1] == "rgb")
        assert cloud.header.frame_id == "map" and cloud.width > 100
        spheres = probe.wait_for_message(topics.VIZ_PHOSPHENES, MarkerArray, timeout=60,
                                         predicate=lambda m: len(m.markers) == 2)
        assert spheres.markers[1].ns == "phosphenes" and len(spheres.markers[1].points) > 100

        # parameters: read, set (reaches the spv node and its output), refused with the reason shown
        assert client.get_parameters(["/spv.mode"]) == {"/spv.mode": "chess_floor"}
        assert "/spv.mode" in client.get_parameters()                          # every node's parameters
        assert client.set_parameters({"/spv.mode": "depth"}) == {"/spv.mode": "depth"}
        assert probe.get_params("spv", ["mode"]) == {"mode": "depth"}
        probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=30, predicate=lambda f: f.mode == "depth")
        assert client.set_parameters({"/spv.mode": "nonsense"}) == {"/spv.mode": "depth"}
        client.pump(1.0)
        assert any("spv.mode" in s and "nonsense" in s for s in client.statuses)

        client.subscribe(["/raspv/latency"])
        assert b"camera_to_display_ms" in client.messages("/raspv/latency", timeout=60)[0].payload
        client.unsubscribe([topics.SPV_IMAGE])
        _wait(lambda: not _foxglove_subscribes(probe, topics.SPV_IMAGE), "the node still takes /spv/image")


def matching(client, collector, topic, cls, timeout=90.0):
    """A message the Foxglove client received that the probe also received (same stamp): under
    load either side may miss a sample of a keep-last-2 topic, so look until one pair shows."""
    import time
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        client.pump(0.3)
        with collector._cond:
            seen = {(_stamp(m).sec, _stamp(m).nanosec): m for m in collector.messages}
        for got in reversed([r for r in client.inbox if r.topic == topic][-20:]):
            msg = deserialize_message(got.payload, cls)
            stamp = _stamp(msg)
            if (stamp.sec, stamp.nanosec) in seen:
                return got, msg, seen[(stamp.sec, stamp.nanosec)]
    raise TimeoutError(f"{topic}: no message both the Foxglove client and the probe received")


def same_values(a, b) -> bool:
    """Field-by-field equality of two ROS messages, NaN equal to NaN."""
    if hasattr(a, "get_fields_and_field_types"):
        return type(a) is type(b) and all(same_values(getattr(a, f), getattr(b, f)) for f in a.get_fields_and_field_types())
    if type(a).__name__ in ("array", "ndarray"):                  # numeric arrays (image data, levels)
        x, y = np.asarray(a), np.asarray(b)
        return x.shape == y.shape and np.array_equal(x, y, equal_nan=x.dtype.kind == "f")
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same_values(x, y) for x, y in zip(a, b))
    if isinstance(a, float):
        return a == b or (a != a and b != b)
    return a == b


@pytest.mark.integration
def test_a_busy_port_is_one_line(graph):
    import socket
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        g = graph({"launch": {"nodes": ["foxglove"]}, "foxglove": {"ros__parameters": {"port": busy.getsockname()[1]}}})
        line = g.wait_for_output(r"\[foxglove\] configuration error: [^\n]*", timeout=60).group(0)
    assert "cannot serve on 127.0.0.1:" in line and "in use" in line
    _wait(lambda: not g.running(), "the graph did not stop")
    assert g.stop() == 1 and "Traceback" not in g.output


def _stamp(m):
    return m.markers[0].header.stamp if isinstance(m, MarkerArray) else m.header.stamp


def _foxglove_subscribes(probe, topic: str) -> bool:
    # (the foxglove node takes its forwarded topics on a node of its own: raspv_viz.raw_forwarder)
    return any(i.node_name == "foxglove_forward" for i in probe.node.get_subscriptions_info_by_topic(topic))


def _wait(condition, failure: str, timeout: float = 30.0) -> None:
    import time
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, failure
        time.sleep(0.1)


def test_token_gate_off_loopback_and_subscription_counting():
    events = []
    server = FoxgloveServer(ServerConfig(host="0.0.0.0", port=0, sysinfo_topic=""),
                            on_first_subscriber=lambda t: events.append(("first", t)),
                            on_last_unsubscribed=lambda t: events.append(("last", t)))
    server.start()
    try:
        assert server.token and re.search(r"/\?token=", server.url())
        server.add_channel("/chatter", "std_msgs/msg/String", ros2msg_schema("std_msgs/msg/String"))
        plain = f"ws://127.0.0.1:{server.port}"
        for wrong in (plain, plain + "/?token=nope"):
            with pytest.raises(InvalidStatus, match="403"):
                FoxgloveClient(wrong)
        with FoxgloveClient(server.url().replace("0.0.0.0", "127.0.0.1")) as a, FoxgloveClient(server.url()) as b:
            for c in (a, b):
                c.wait_for_channels(["/chatter"], timeout=30)
                c.subscribe(["/chatter"])
            _wait(lambda: server.watchers("/chatter") == 2, "subscriptions not seen", 30)
            payload = serialize_message(_string("hello"))
            server.log("/chatter", payload, 42)
            for c in (a, b):
                got = c.messages("/chatter", timeout=30)[0]
                assert got.payload == payload and got.log_time_ns == 42
            a.unsubscribe(["/chatter"])
            _wait(lambda: server.watchers("/chatter") == 1, "unsubscribe not seen", 30)   # b still watches
            b.unsubscribe(["/chatter"])
            _wait(lambda: not server.watched("/chatter"), "last unsubscribe not seen", 30)
        assert events == [("first", "/chatter"), ("last", "/chatter")]
    finally:
        server.stop()


def _string(text: str):
    from std_msgs.msg import String
    return String(data=text)


def test_ros2msg_schemas_name_every_dependency():
    text = ros2msg_schema("raspv_msgs/msg/StairDetection").decode()
    blocks = [b.strip().splitlines()[0] for b in text.split("=" * 80)[1:]]
    assert set(blocks) == {"MSG: std_msgs/Header", "MSG: builtin_interfaces/Time", "MSG: geometry_msgs/Pose",
                           "MSG: geometry_msgs/Point", "MSG: geometry_msgs/Quaternion", "MSG: raspv_msgs/Step"}
    assert ros2msg_schema("visualization_msgs/msg/MarkerArray") is not None
    assert ros2msg_schema("nobody_msgs/msg/Nothing") is None


def test_latency_sample_from_a_raw_phosphene_frame():
    from builtin_interfaces.msg import Time

    from raspv_viz.foxglove_node import latency_sample
    frame = PhospheneFrame(mode="depth", brightness=[0.5] * 1000, levels=[3] * 1000)
    frame.header.stamp, frame.source_stamp, frame.scene_stamp = Time(sec=10, nanosec=50_000_000), \
        Time(sec=10, nanosec=10_000_000), Time(sec=9, nanosec=960_000_000)
    sample = latency_sample(serialize_message(frame))
    assert sample["mode"] == "depth"
    assert sample["camera_to_display_ms"] == pytest.approx(40.0) and sample["scene_age_ms"] == pytest.approx(50.0)
    frame.scene_stamp = Time()
    assert "scene_age_ms" not in latency_sample(serialize_message(frame))        # no scene result used


def test_stop_is_bounded_with_a_client_that_stopped_reading():
    """A subscribed client that no longer reads (its queue full) held foxglove-sdk's stop until the
    client's TCP failed (46 s here, past the launcher's SIGINT grace). stop() waits STOP_WAIT_S."""
    import time

    from raspv_viz.foxglove_server import STOP_WAIT_S
    server = FoxgloveServer(ServerConfig(port=0, sysinfo_topic=""), lambda t: None, lambda t: None)
    server.start()
    server.add_channel("/img", "sensor_msgs/msg/Image", ros2msg_schema("sensor_msgs/msg/Image"))
    client = FoxgloveClient(server.url())
    try:
        client.wait_for_channels(["/img"], timeout=30)
        client.subscribe(["/img"])
        _wait(lambda: server.watched("/img"), "subscription not seen", 30)
        for i in range(60):                           # 38 MB the client never reads (its socket and queue hold ~15)
            server.log("/img", bytes(640_000), i)
        started = time.monotonic()
        server.stop()
        assert time.monotonic() - started < STOP_WAIT_S + 10.0     # a hang bound, not a timing figure
    finally:
        try:
            client.close()
        except Exception:   # the server went away under it
            pass


def test_without_the_extra_the_node_says_so_in_one_line():
    """A graph with a foxglove node on an install without the extra: the node exits with one line
    naming the command that installs it, not a traceback."""
    import subprocess
    import sys

    code = ("import sys; sys.modules['foxglove'] = None  # as if foxglove-sdk were not installed\n"
            "from raspv_bringup.node_entry import main; main(['raspv_viz.foxglove_node'])")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 1 and len(lines) == 1, res.stderr
    assert "'foxglove' extra" in lines[0] and "EXTRAS=foxglove" in lines[0], lines[0]


def test_a_client_offering_only_the_old_subprotocol_is_told_why(caplog):
    """Issue 36: a client offering only foxglove.websocket.v1 got a bare HTTP 400 and the node's
    log said "handshake failed": on loopback (the SDK itself answers) the log says why; behind the
    gate the answer does."""
    import asyncio

    from websockets.asyncio.client import connect

    async def offer_old(url):
        with pytest.raises(InvalidStatus) as refused:
            async with connect(url, subprotocols=["foxglove.websocket.v1"], open_timeout=30):
                pass
        return refused.value.response

    for host in ("127.0.0.1", "0.0.0.0"):
        server = FoxgloveServer(ServerConfig(host=host, port=0, sysinfo_topic=""), lambda t: None, lambda t: None)
        server.start()
        try:
            with caplog.at_level("ERROR", logger="foxglove.websocket.server"):
                response = asyncio.run(offer_old(server.url().replace("0.0.0.0", "127.0.0.1")))
                if host == "127.0.0.1":
                    _wait(lambda: any("handshake failed" in r.getMessage() for r in caplog.records), "no log line", 10)
        finally:
            server.stop()
        assert response.status_code == 400
        if host == "127.0.0.1":
            line = next(r.getMessage() for r in caplog.records if "handshake failed" in r.getMessage())
            assert "foxglove.sdk.v1" in line and "foxglove.websocket.v1" in line, line
        else:
            assert b"offered foxglove.websocket.v1" in response.body and b"foxglove.sdk.v1" in response.body
