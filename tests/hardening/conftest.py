"""Fixtures of the hardening tests: a headset server core on free loopback ports, and raw
WebSocket/TCP clients that misbehave on purpose (every loop bounded)."""
from __future__ import annotations

import asyncio
import json
from typing import Any

import pytest
from websockets.asyncio.client import connect

from raspv_hmd import protocol as P
from raspv_hmd.server import Callbacks, HeadsetServer, ServerConfig


@pytest.fixture
def server_events() -> list[str]:
    return []


@pytest.fixture
def start_server(server_events):
    started: list[HeadsetServer] = []

    def start(**config: Any) -> HeadsetServer:
        config.setdefault("host", "127.0.0.1")
        config.setdefault("port", 0)
        config.setdefault("tcp_port", 0)
        server = HeadsetServer(ServerConfig(**config), Callbacks(on_event=server_events.append)).start()
        started.append(server)
        return server

    yield start
    for s in started:
        s.stop()


async def ws_connect(server):
    # max_queue=None: a client that stops reading must not stall its own closing handshake
    return await connect(f"ws://127.0.0.1:{server.port}/ws", max_size=None, compression=None, max_queue=None,
                         ping_interval=None)


async def ws_hello(server, **hello):
    """A WebSocket client that sent its hello; returns (connection, the server's answer)."""
    ws = await ws_connect(server)
    await ws.send(P.client_message("hello", **hello))
    return ws, await ws_next_json(ws)


async def ws_next_json(ws, kind: str | None = None, timeout: float = 5.0) -> dict:
    while True:
        msg = await asyncio.wait_for(ws.recv(), timeout)
        if isinstance(msg, str):
            m = json.loads(msg)
            if kind is None or m["type"] == kind:
                return m


class TcpClient:
    """A raw native client: length-prefixed messages of any kind, or raw bytes."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer

    @classmethod
    async def open(cls, server) -> "TcpClient":
        return cls(*await asyncio.open_connection("127.0.0.1", server.tcp_port))

    async def send(self, data: bytes | str, kind: int = P.TCP_JSON) -> None:
        data = data.encode() if isinstance(data, str) else data
        self.writer.write(P.TCP_HEADER.pack(len(data), kind) + data)
        await self.writer.drain()

    async def next_json(self, kind: str | None = None, timeout: float = 5.0) -> dict:
        while True:
            n, k = P.TCP_HEADER.unpack(await asyncio.wait_for(self.reader.readexactly(P.TCP_HEADER.size), timeout))
            data = await asyncio.wait_for(self.reader.readexactly(n), timeout)
            if k == P.TCP_JSON:
                m = json.loads(data)
                if kind is None or m["type"] == kind:
                    return m

    async def closed_by_server(self, timeout: float) -> bool:
        """True when the server closes the connection within ``timeout`` s (reads and discards)."""
        try:
            while await asyncio.wait_for(self.reader.read(65536), timeout):
                pass
            return True
        except asyncio.TimeoutError:
            return False
        except ConnectionError:
            return True

    def close(self) -> None:
        self.writer.close()
