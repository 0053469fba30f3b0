"""One headset client's session, shared by the links (no rclpy): what it asked for (format,
window, role), what it was sent and refused, its message budget, and the transport it came by
(:class:`Link`: :mod:`raspv_hmd.websocket_link` for the browser page, :mod:`raspv_hmd.tcp_link`
for native clients). The server (:mod:`raspv_hmd.server`) runs the protocol over any link.
"""
from __future__ import annotations

import asyncio
import collections
import statistics
import time
from dataclasses import dataclass
from typing import Protocol

from raspv_hmd import protocol as P

HARD_MESSAGE_LIMIT = 65536          # bytes; a client sending more than this in one message is dropped
CLOSE_TIMEOUT_S = 1.0               # wait this long for a client's closing handshake, then close the socket


class Drop(Exception):
    """The client must be disconnected; ``code`` is counted like a refusal."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


@dataclass
class ClientStats:
    id: int
    name: str
    peer: str
    transport: str
    role: str
    format: str
    received: int
    refused: dict[str, int]
    ignored: int
    frames_sent: int
    frames_skipped: int
    ack_rtt_ms: float | None


class Link(Protocol):
    """One client's transport: JSON text and frames out, messages in (``recv`` → None when the
    client closed)."""

    transport: str
    said_bye: bool                       # set by the server's bye: close() then expects only the closing handshake

    async def send_text(self, text: str) -> None: ...
    async def send_frame(self, data: bytes) -> None: ...
    async def recv(self) -> str | bytes | None: ...
    async def close(self) -> None: ...
    def cut(self) -> None: ...


class ClientSession:
    def __init__(self, cid: int, link: Link, peer: str, remote: bool, hello: P.Hello, compression: str,
                 max_rate: float) -> None:
        self.id = cid
        self.link = link
        self.peer = peer
        self.name = hello.name or f"client {cid}"
        wanted = hello.format if hello.format != "auto" else compression
        image = wanted if wanted in ("raw", "png") else "png" if remote else "raw"
        self.image_format = P.FORMAT_PNG if image == "png" else P.FORMAT_RAW   # images when levels cannot be sent
        self.format = P.FORMAT_LEVELS if wanted == "levels" else self.image_format
        self.sprites_sent = -1                       # map id of the sprites this client has (levels stream)
        self.window = hello.window
        self.received = 0
        self.refused: collections.Counter[str] = collections.Counter()
        self.ignored = 0
        self.frames_sent = 0
        self.frames_skipped = 0
        self.last_sent = 0
        self.in_flight: collections.deque[tuple[int, float]] = collections.deque()   # (seq, sent time)
        self.ack_rtts: collections.deque[float] = collections.deque(maxlen=200)
        self.frame_ready = asyncio.Event()
        self.acked = asyncio.Event()
        self.wants_control = hello.role == "control"
        self.last_active = time.monotonic()          # last head/twist/key/param message (or the hello)
        self.evicted: str | None = None              # why the server made room with this client
        self.task: asyncio.Task | None = None
        self.tokens = max_rate
        self.max_rate = max_rate
        self.last_refill = time.monotonic()

    def take_token(self, now: float) -> bool:
        self.tokens = min(self.max_rate, self.tokens + (now - self.last_refill) * self.max_rate)
        self.last_refill = now
        if self.tokens < 1.0:
            return False
        self.tokens -= 1.0
        return True

    def stats(self, role: str) -> ClientStats:
        return ClientStats(self.id, self.name, self.peer, self.link.transport, role, P.FORMAT_NAMES[self.format],
                           self.received, dict(self.refused), self.ignored, self.frames_sent, self.frames_skipped,
                           statistics.median(self.ack_rtts) if self.ack_rtts else None)
