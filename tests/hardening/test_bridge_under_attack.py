"""The hostile-client cases against a running `bridge` node (loopback only, bounded loops): every
slot held by pinging clients (a controller and watchers), garbage, binary hellos and a client that stops reading — and the
headset that wants control still gets in and receives the phosphene frames."""
from __future__ import annotations

import asyncio
import json

import numpy as np
import websockets
import pytest
from sensor_msgs.msg import Image

from raspv_common import topics
from raspv_common.conversions import array_to_image
from raspv_common.qos import SENSOR_QOS
from raspv_hmd import protocol as P

from .conftest import TcpClient, ws_connect, ws_hello, ws_next_json

pytestmark = pytest.mark.integration

URL = r"open http://127\.0\.0\.1:(\d+)/ in a browser; native clients: tcp://127\.0\.0\.1:(\d+)"


async def got_bye(ws, quiet_s: float = 1.0) -> bool:
    """Whether ``ws`` is sent a ``bye`` (other messages — role announcements — come first) before
    it has been quiet for ``quiet_s`` or is closed."""
    while True:
        try:
            msg = await asyncio.wait_for(ws.recv(), quiet_s)
        except (asyncio.TimeoutError, websockets.ConnectionClosed):
            return False
        if isinstance(msg, str) and json.loads(msg)["type"] == "bye":
            return True


def test_a_headset_gets_in_and_streams_while_the_bridge_is_attacked(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "bridge"}]},
               "bridge": {"ros__parameters": {"port": 0, "tcp_port": 0, "max_clients": 16}}})
    m = g.wait_for_output(URL, timeout=60)

    class Port:                                             # what the client helpers need of a server
        port, tcp_port = int(m.group(1)), int(m.group(2))

    # (the bridge subscribes to /spv/image once clients that want images connect)
    pub = probe.publisher(topics.SPV_IMAGE, Image, qos=SENSOR_QOS)
    image = array_to_image(np.full((120, 160), 128, np.uint8), "mono8")

    async def run():
        pingers = []
        for i in range(16):                                   # a controller, then watchers
            ws, welcome = await ws_hello(Port, name=f"pinger {i}", role="control" if i == 0 else "watch")
            assert welcome["type"] == "welcome"
            pingers.append(ws)
        binary = await ws_connect(Port)
        await binary.send(b"\x00binary hello")
        assert (await ws_next_json(binary, "bye"))["type"] == "bye"
        junk = await TcpClient.open(Port)
        await junk.send(b"\xff" * 100, kind=P.TCP_FRAME)
        assert (await junk.next_json("bye"))["type"] == "bye"
        headset, welcome = await ws_hello(Port, name="headset", role="control")
        assert welcome["type"] == "welcome", welcome
        evicted = sum(await asyncio.gather(*(got_bye(ws) for ws in pingers)))
        assert evicted == 1
        for _ in range(200):                                  # frames reach the headset
            pub.publish(image)
            try:
                msg = await asyncio.wait_for(headset.recv(), 0.1)
            except asyncio.TimeoutError:
                continue
            if isinstance(msg, bytes):
                header, _ = P.unpack_frame(msg)
                assert (header.width, header.height) == (160, 120)
                break
        else:
            raise AssertionError("no frame reached the headset")
        for ws in [*pingers, headset, binary]:
            await ws.close()

    asyncio.run(run())
    assert g.running()
    g.stop()
    assert "Traceback" not in g.output
    assert "evicted" in g.output
