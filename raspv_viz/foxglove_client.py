"""A minimal Foxglove WebSocket client (no rclpy): what the tests and ``raspv bench foxglove``
use in place of the Foxglove app, speaking the same protocol with ``websockets``.

Server → client: JSON ``serverInfo``, ``advertise`` / ``unadvertise`` (channels: id, topic,
encoding, schemaName, schema, schemaEncoding), ``parameterValues``, ``status``; binary
``messageData`` frames: opcode 0x01, u32 subscription id, u64 log time [ns], payload (little
endian). Client → server: ``subscribe`` / ``unsubscribe``, ``getParameters``, ``setParameters``.
"""
from __future__ import annotations

import itertools
import json
import struct
import time
from dataclasses import dataclass
from typing import Any

from websockets.sync.client import connect

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]   # foxglove-sdk 0.30 accepts only the first
MESSAGE_DATA = 0x01


@dataclass
class Received:
    topic: str
    log_time_ns: int
    payload: bytes


class FoxgloveClient:
    def __init__(self, url: str, open_timeout: float = 10.0) -> None:
        # no keepalive pings: a client between two pumps does not read, so its pong waits behind the
        # frames queued before it and websockets closed the connection (1011) on a loaded machine
        self._connection = connect(url, subprotocols=SUBPROTOCOLS, max_size=None, open_timeout=open_timeout,
                                   compression=None, ping_interval=None)
        self.ws = self._connection.__enter__()
        self.server_info: dict[str, Any] = {}
        self.channels: dict[str, dict[str, Any]] = {}      # topic → advertised channel
        self.statuses: list[str] = []
        self._subs: dict[int, str] = {}                     # subscription id → topic
        self._ids = itertools.count(1)
        self._answers: dict[str, list[dict[str, Any]]] = {}
        self.inbox: list[Received] = []
        self.keep = True                                    # False: only count (long benchmark runs)
        self.counts: dict[str, int] = {}                    # topic → messages received
        self.bytes: dict[str, int] = {}                     # topic → payload bytes received

    def close(self) -> None:
        self._connection.__exit__(None, None, None)

    def __enter__(self) -> "FoxgloveClient":
        return self

    def __exit__(self, *_: Any) -> None:
        self.close()

    # -- receiving ---------------------------------------------------------------------------
    def pump(self, timeout: float) -> None:
        """Handle whatever arrives within ``timeout`` s (at least one frame if one comes)."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                frame = self.ws.recv(timeout=max(0.0, deadline - time.monotonic()))
            except TimeoutError:
                return
            self._handle(frame)
            if time.monotonic() >= deadline:
                return

    def _handle(self, frame: str | bytes) -> None:
        if isinstance(frame, bytes):
            if frame and frame[0] == MESSAGE_DATA:
                sub, log_time = struct.unpack_from("<IQ", frame, 1)
                topic = self._subs.get(sub)
                if topic is not None:
                    self.counts[topic] = self.counts.get(topic, 0) + 1
                    self.bytes[topic] = self.bytes.get(topic, 0) + len(frame) - 13
                    if self.keep:
                        self.inbox.append(Received(topic, log_time, frame[13:]))
            return
        msg = json.loads(frame)
        op = msg.get("op")
        if op == "serverInfo":
            self.server_info = msg
        elif op == "advertise":
            for ch in msg["channels"]:
                self.channels[ch["topic"]] = ch
        elif op == "unadvertise":
            gone = set(msg["channelIds"])
            self.channels = {t: c for t, c in self.channels.items() if c["id"] not in gone}
        elif op == "parameterValues":
            self._answers.setdefault(msg.get("id", ""), []).extend(msg["parameters"])
        elif op == "status":
            self.statuses.append(msg.get("message", ""))

    def wait_for_channels(self, topics: list[str], timeout: float = 30.0) -> dict[str, dict[str, Any]]:
        deadline = time.monotonic() + timeout
        while not all(t in self.channels for t in topics):
            if time.monotonic() > deadline:
                missing = [t for t in topics if t not in self.channels]
                raise TimeoutError(f"not advertised within {timeout:.0f} s: {missing} (have {sorted(self.channels)})")
            self.pump(0.2)
        return {t: self.channels[t] for t in topics}

    # -- subscriptions -----------------------------------------------------------------------
    def subscribe(self, topics: list[str]) -> None:
        subs = []
        for topic in topics:
            sid = next(self._ids)
            self._subs[sid] = topic
            subs.append({"id": sid, "channelId": self.channels[topic]["id"]})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    def unsubscribe(self, topics: list[str]) -> None:
        ids = [sid for sid, t in self._subs.items() if t in topics]
        for sid in ids:
            del self._subs[sid]
        self.ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": ids}))

    def messages(self, topic: str, count: int = 1, timeout: float = 30.0) -> list[Received]:
        """The first ``count`` messages received on ``topic`` (waiting up to ``timeout`` s)."""
        deadline = time.monotonic() + timeout
        while sum(r.topic == topic for r in self.inbox) < count:
            if time.monotonic() > deadline:
                raise TimeoutError(f"{topic}: {sum(r.topic == topic for r in self.inbox)} of {count} messages "
                                   f"within {timeout:.0f} s")
            self.pump(0.2)
        return [r for r in self.inbox if r.topic == topic][:count]

    # -- parameters --------------------------------------------------------------------------
    def _request(self, body: dict[str, Any], timeout: float) -> list[dict[str, Any]]:
        rid = f"r{next(self._ids)}"
        self.ws.send(json.dumps({**body, "id": rid}))
        deadline = time.monotonic() + timeout
        while rid not in self._answers:
            if time.monotonic() > deadline:
                raise TimeoutError(f"no answer to {body['op']} within {timeout:.0f} s")
            self.pump(0.2)
        return self._answers.pop(rid)

    def get_parameters(self, names: list[str] | None = None, timeout: float = 30.0) -> dict[str, Any]:
        return {p["name"]: p.get("value") for p in self._request({"op": "getParameters", "parameterNames": names or []},
                                                                  timeout)}

    def set_parameters(self, values: dict[str, Any], timeout: float = 30.0) -> dict[str, Any]:
        params = [{"name": n, "value": v} for n, v in values.items()]
        return {p["name"]: p.get("value") for p in self._request({"op": "setParameters", "parameters": params}, timeout)}
