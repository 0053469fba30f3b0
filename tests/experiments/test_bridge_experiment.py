"""The headset bridge in a real graph carries experiments both ways: /experiment/instructions (latched)
reach a WebSocket client, and the client's start/abort come back on /experiment/response."""
from __future__ import annotations

import asyncio
import json

import pytest
from std_msgs.msg import String
from websockets.asyncio.client import connect

from raspv_common import topics
from raspv_common.qos import EVENT_QOS, LATCHED_QOS
from raspv_hmd import protocol as P
from raspv_hmd.reference_client import parse_endpoint

pytestmark = pytest.mark.integration
URL = r"open (http://127\.0\.0\.1:(\d+)/) in a browser"


def test_instructions_and_answers_through_the_bridge(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "bridge"}]}, "bridge": {"ros__parameters": {"port": 0, "tcp_port": -1}}})
    url = g.wait_for_output(URL, timeout=60).group(1)
    answers = probe.subscribe(topics.EXPERIMENT_RESPONSE, String, qos=EVENT_QOS)
    pub = probe.publisher(topics.EXPERIMENT_INSTRUCTIONS, String, qos=LATCHED_QOS, wait_for_subscribers=1, timeout=60)
    pub.publish(String(data=json.dumps({"id": "S01-1-1", "trial": 1, "title": "Trial 1", "text": "Go.",
                                        "waiting": True})))

    async def client():
        async with connect(parse_endpoint(url).ws_url, max_size=None, compression=None) as ws:
            await ws.send(P.client_message("hello", name="test", role="control"))
            while True:                                        # instructions come even to a late client
                msg = await asyncio.wait_for(ws.recv(), 30)
                if isinstance(msg, str) and json.loads(msg)["type"] == "instructions":
                    shown = json.loads(msg)
                    break
            await ws.send(P.client_message("experiment", action="start", id=shown["id"]))
            await ws.send(P.client_message("experiment", action="abort", id=shown["id"]))
            await ws.send(P.client_message("experiment", action="stop"))          # refused, not forwarded
            while True:
                msg = await asyncio.wait_for(ws.recv(), 30)
                if isinstance(msg, str) and json.loads(msg)["type"] == "refused":
                    return shown

    shown = asyncio.run(client())
    assert (shown["id"], shown["text"], shown["waiting"]) == ("S01-1-1", "Go.", True)
    got = [json.loads(m.data) for m in answers.wait(2, timeout=30)]
    assert [(a["action"], a["id"]) for a in got] == [("start", "S01-1-1"), ("abort", "S01-1-1")]
