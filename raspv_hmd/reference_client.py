"""Python reference client of the headset protocol (WebSocket or TCP; no rclpy).

It does what a headset does — receives frames and acknowledges them once "shown", sends a
scripted head motion, pings — and measures: frames per second, image time → received latency
(using a clock offset estimated NTP-style from ping/pong, so it also works across machines),
and round-trip times. ``raspv hmd-client`` is its command line; the benchmark and the tests
drive it directly. Native client authors can read it next to docs/hmd.md.
"""
from __future__ import annotations

import asyncio
import json
import math
import socket
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol
from urllib.parse import parse_qs, urlsplit

import numpy as np

from raspv_hmd import protocol as P


class ClientError(Exception):
    """The client could not connect or the server refused it; ``str()`` says why."""


@dataclass(frozen=True)
class Endpoint:
    transport: str        # "websocket" or "tcp"
    host: str
    port: int
    secure: bool = False
    token: str = ""

    @property
    def ws_url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{'wss' if self.secure else 'ws'}://{host}:{self.port}/ws"


def parse_endpoint(url: str, token: str = "") -> Endpoint:
    """``http(s)://host:port/?token=…`` (the URL the bridge prints), ``ws(s)://host:port/ws`` or
    ``tcp://host:port`` → Endpoint; ValueError with an example when it is none of these."""
    parts = urlsplit(url)
    if parts.scheme not in ("http", "https", "ws", "wss", "tcp") or not parts.hostname:
        raise ValueError(f"cannot use {url!r}: give the URL the bridge printed (http://127.0.0.1:8765/), "
                         "or tcp://HOST:PORT for its TCP endpoint")
    try:
        port = parts.port
    except ValueError:
        raise ValueError(f"bad port in {url!r}") from None
    if port is None:
        if parts.scheme == "tcp":
            raise ValueError(f"{url!r} needs a port, e.g. tcp://127.0.0.1:8766")
        port = 443 if parts.scheme in ("https", "wss") else 80
    token = token or parse_qs(parts.query).get("token", [""])[0]
    transport = "tcp" if parts.scheme == "tcp" else "websocket"
    return Endpoint(transport, parts.hostname, port, parts.scheme in ("https", "wss"), token)


@dataclass
class HeadScript:
    """Scripted head motion: yaw = A·sin(2πt/T), pitch = B·sin(2πt/(1.5T)); degrees, seconds."""

    yaw_deg: float = 30.0
    pitch_deg: float = 10.0
    period_s: float = 4.0

    def at(self, t: float) -> tuple[float, float, float]:
        """(roll, pitch, yaw) in radians at time ``t`` s."""
        w = 2 * math.pi * t / self.period_s
        return 0.0, math.radians(self.pitch_deg) * math.sin(w / 1.5), math.radians(self.yaw_deg) * math.sin(w)


@dataclass
class ClientOptions:
    role: str = "control"             # "control" or "watch"
    format: str = "auto"              # "auto", "raw", "png"
    window: int = 2                   # frames in flight before an ack
    duration_s: float = 10.0
    max_frames: int | None = None     # stop after this many frames
    head: HeadScript | None = field(default_factory=HeadScript)
    head_rate_hz: float = 50.0
    gaze: Any = None                  # an object with at(t) → unit gaze direction (head frame) or None; None: no gaze
    gaze_rate_hz: float = 120.0
    ping_hz: float = 2.0
    name: str = "raspv hmd-client"
    keep_last_frame: bool = False
    on_frame: Callable[[float, P.FrameHeader, np.ndarray], None] | None = None   # (receipt time, header, image)


@dataclass
class ClientReport:
    transport: str = ""
    client_id: int | None = None
    role: str = ""
    format: str = ""
    frames: int = 0
    bytes: int = 0
    elapsed_s: float = 0.0
    size: tuple[int, int] | None = None
    formats_seen: dict[str, int] = field(default_factory=dict)
    latency_ms: list[float] = field(default_factory=list)     # image time → received (server clock)
    rtt_ms: list[float] = field(default_factory=list)
    clock_offset_s: float | None = None                       # server clock − this clock
    heads_sent: list[tuple[float, tuple[float, float, float, float]]] = field(default_factory=list)
    gazes_sent: list[tuple[float, tuple[float, float, float] | None]] = field(default_factory=list)
    messages: list[dict] = field(default_factory=list)        # status/refused/role/bye from the server
    closed: str = ""
    last_frame: np.ndarray | None = None

    @property
    def fps(self) -> float:
        return self.frames / self.elapsed_s if self.elapsed_s > 0 else 0.0

    def to_json(self) -> dict:
        return {"transport": self.transport, "client_id": self.client_id, "role": self.role, "format": self.format,
                "frames": self.frames, "bytes": self.bytes, "elapsed_s": self.elapsed_s, "fps": self.fps,
                "size": self.size, "formats_seen": self.formats_seen, "latency_ms": self.latency_ms,
                "rtt_ms": self.rtt_ms, "clock_offset_s": self.clock_offset_s,
                "heads_sent": self.heads_sent, "messages": self.messages, "closed": self.closed}


def decode_payload(header: P.FrameHeader, payload: memoryview) -> np.ndarray:
    """Frame payload → (H, W) or (H, W, 3) uint8 (RGB order); a FLAG_GREEN frame → rgb8 with only
    the green channel, as it was published."""
    import cv2

    if header.format == P.FORMAT_RAW:
        arr = np.frombuffer(payload, np.uint8)
        img = arr.reshape(header.height, header.width) if header.channels == 1 else \
            arr.reshape(header.height, header.width, 3)
    else:
        img = cv2.imdecode(np.frombuffer(payload, np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise P.ProtocolError("bad_frame", "PNG payload could not be decoded")
        if img.ndim == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    if header.flags & P.FLAG_GREEN and img.ndim == 2:
        rgb = np.zeros(img.shape + (3,), np.uint8)
        rgb[..., 1] = img
        return rgb
    return img


class _Conn(Protocol):
    """A connection to the server: JSON text out, JSON text or frame bytes in (None: closed)."""

    async def send(self, text: str) -> None: ...
    async def recv(self) -> str | bytes | None: ...
    async def close(self) -> None: ...


class _WsConn:
    def __init__(self, ws) -> None:
        self.ws = ws

    async def send(self, text: str) -> None:
        await self.ws.send(text)

    async def recv(self) -> str | bytes | None:
        from websockets.exceptions import ConnectionClosed
        try:
            return await self.ws.recv()
        except ConnectionClosed:
            return None

    async def close(self) -> None:
        await self.ws.close()


class _TcpConn:
    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer

    async def send(self, text: str) -> None:
        data = text.encode()
        self.writer.write(P.TCP_HEADER.pack(len(data), P.TCP_JSON) + data)
        await self.writer.drain()

    async def recv(self) -> str | bytes | None:
        try:
            n, kind = P.TCP_HEADER.unpack(await self.reader.readexactly(P.TCP_HEADER.size))
            data = await self.reader.readexactly(n)
        except (asyncio.IncompleteReadError, ConnectionError):
            return None
        return data.decode() if kind == P.TCP_JSON else data

    async def close(self) -> None:
        self.writer.close()
        try:
            await self.writer.wait_closed()
        except OSError:
            pass


async def _open(ep: Endpoint, timeout: float) -> _Conn:
    import ssl

    ctx = None
    if ep.secure:     # self-signed certificates are the norm for a lab bridge
        ctx = ssl.create_default_context()
        ctx.check_hostname = False
        ctx.verify_mode = ssl.CERT_NONE
    try:
        if ep.transport == "tcp":
            reader, writer = await asyncio.wait_for(asyncio.open_connection(ep.host, ep.port), timeout)
            writer.get_extra_info("socket").setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            return _TcpConn(reader, writer)
        from websockets.asyncio.client import connect
        from websockets.exceptions import InvalidStatus
        try:
            ws = await connect(ep.ws_url, max_size=2**28, compression=None, open_timeout=timeout, ssl=ctx,
                               ping_interval=None)
        except InvalidStatus as exc:
            body = exc.response.body.decode(errors="replace").strip()
            raise ClientError(f"{ep.ws_url} answered HTTP {exc.response.status_code}: {body}") from None
        return _WsConn(ws)
    except (OSError, asyncio.TimeoutError) as exc:
        why = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
        raise ClientError(f"cannot connect to {ep.host}:{ep.port} ({ep.transport}): {why} — is the bridge running?") from None


async def run_client(endpoint: Endpoint, options: ClientOptions | None = None, connect_timeout: float = 5.0) -> ClientReport:
    """Connect, stream for ``options.duration_s`` (or ``max_frames``), and report."""
    opt = options or ClientOptions()
    report = ClientReport(transport=endpoint.transport)
    conn = await _open(endpoint, connect_timeout)
    await conn.send(P.client_message("hello", protocol=P.PROTOCOL_VERSION, token=endpoint.token, name=opt.name,
                                     role=opt.role, format=opt.format, window=opt.window))
    welcome = await asyncio.wait_for(conn.recv(), connect_timeout)
    if welcome is None:
        raise ClientError("the server closed the connection during the hello")
    first = json.loads(welcome)
    if first.get("type") != "welcome":
        await conn.close()
        raise ClientError(f"the server refused this client: {first.get('reason', first)}")
    report.client_id, report.role, report.format = first["client_id"], first["role"], first["format"]
    pings: dict[float, float] = {}
    offsets: list[tuple[float, float]] = []      # (rtt, offset)
    received: list[tuple[float, float]] = []     # (receipt time, image stamp)
    start = time.time()
    done = asyncio.Event()

    async def receive() -> None:
        while not done.is_set():
            msg = await conn.recv()
            now = time.time()
            if msg is None:
                report.closed = report.closed or "the server closed the connection"
                break
            if isinstance(msg, str):
                m = json.loads(msg)
                if m.get("type") == "pong" and m.get("t") in pings:
                    t0 = pings.pop(m["t"])
                    rtt = now - t0
                    report.rtt_ms.append(1e3 * rtt)
                    offsets.append((rtt, m["server_time"] - (t0 + now) / 2))
                elif m.get("type") in ("status", "refused", "role", "bye"):
                    report.messages.append(m)
                    if m["type"] == "role":
                        report.role = m["role"]
                    if m["type"] == "bye":
                        report.closed = m.get("reason", "bye")
                continue
            header, payload = P.unpack_frame(msg)
            received.append((now, header.stamp))
            report.frames += 1
            report.bytes += len(msg)
            report.size = (header.width, header.height)
            name = P.FORMAT_NAMES[header.format]
            report.formats_seen[name] = report.formats_seen.get(name, 0) + 1
            if opt.keep_last_frame or opt.on_frame is not None:
                image = decode_payload(header, payload).copy()
                if opt.keep_last_frame:
                    report.last_frame = image
                if opt.on_frame is not None:
                    opt.on_frame(now, header, image)
            if opt.window:
                await conn.send(P.client_message("ack", seq=header.seq))
            if opt.max_frames is not None and report.frames >= opt.max_frames:
                break
        done.set()

    async def move_head() -> None:
        if opt.head is None or opt.role != "control":
            return
        period = 1.0 / opt.head_rate_hz
        while not done.is_set():
            t = time.time()
            q = P.rpy_to_quaternion(*opt.head.at(t - start))
            await conn.send(P.client_message("head", q=list(q), t=t))
            report.heads_sent.append((t, q))
            await _sleep_or_done(done, period)

    async def move_eyes() -> None:
        if opt.gaze is None or opt.role != "control":
            return
        period = 1.0 / opt.gaze_rate_hz
        while not done.is_set():
            t = time.time()
            d = opt.gaze.at(t - start)
            await conn.send(P.client_message("gaze", dir=[float(c) for c in d], t=t) if d is not None
                            else P.client_message("gaze", valid=False, t=t))
            report.gazes_sent.append((t, None if d is None else tuple(float(c) for c in d)))
            await _sleep_or_done(done, period)

    async def ping() -> None:
        while not done.is_set():
            t = time.time()
            pings[t] = t
            await conn.send(P.client_message("ping", t=t))
            await _sleep_or_done(done, 1.0 / opt.ping_hz)

    async def timer() -> None:
        await _sleep_or_done(done, opt.duration_s)
        done.set()

    tasks = [asyncio.create_task(c) for c in (receive(), move_head(), move_eyes(), ping(), timer())]
    try:
        await done.wait()
    finally:
        for t in tasks:
            t.cancel()
        results = await asyncio.gather(*tasks, return_exceptions=True)
        await conn.close()
    for r in results:
        if isinstance(r, Exception) and not isinstance(r, asyncio.CancelledError):
            if not _closed_error(r):
                raise r
            report.closed = report.closed or f"connection lost: {r}"
    report.elapsed_s = time.time() - start
    if offsets:
        report.clock_offset_s = min(offsets)[1]
        report.latency_ms = [1e3 * (t + report.clock_offset_s - stamp) for t, stamp in received]
    return report


def _closed_error(exc: BaseException) -> bool:
    from websockets.exceptions import ConnectionClosed
    return isinstance(exc, (ConnectionClosed, ConnectionError))


async def _sleep_or_done(done: asyncio.Event, seconds: float) -> None:
    try:
        await asyncio.wait_for(done.wait(), seconds)
    except asyncio.TimeoutError:
        pass


def percentile(values: list[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if values else None
