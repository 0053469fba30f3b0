"""The headset server: one port for the browser client page (HTTP GET) and its WebSocket, and an
optional plain TCP port for native clients; frames out, head pose and controls in. No rclpy.

It runs an asyncio loop in its own thread. The owner (the ``bridge`` node, a benchmark, a test)
calls :meth:`HeadsetServer.submit_frame` (images) and :meth:`~HeadsetServer.submit_levels` (the
levels stream: per-phosphene weights the client draws from a sprite atlas sent once,
:mod:`raspv_hmd.levels_stream`) from any thread — only the newest frame is kept, so a slow
client skips stale frames instead of queueing them — and gets the controlling client's
input through :class:`Callbacks`, called on the server thread. The protocol is in
``protocol.py`` and docs/hmd.md; who controls is decided by ``control.ControlArbiter``.

Security: binds 127.0.0.1 by default and then only answers requests whose Host is a loopback
name (no DNS rebinding); bound anywhere else it requires a token (generated when not given) in
the page URL and in every client's hello. Client messages above 4 KiB are refused, above
64 KiB the client is dropped; each refused message is counted per client, and a client that
reaches ``max_refused`` refusals, floods, or stays silent for ``idle_timeout_s`` is dropped
without affecting the others.
"""
from __future__ import annotations

import asyncio
import collections
import hmac
import math
import secrets
import ssl
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable
from urllib.parse import parse_qs, urlsplit

import numpy as np
from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed

from raspv_common.thread_priority import DISPLAY_RT_PRIORITY, raise_thread_priority
from raspv_hmd import protocol as P
from raspv_hmd.client_session import CLOSE_TIMEOUT_S, HARD_MESSAGE_LIMIT, ClientSession, ClientStats, Drop, Link
from raspv_hmd.control import ControlArbiter, DeadMan
from raspv_hmd.frame_encoding import LevelsFrame, OutgoingFrame
from raspv_hmd.http_pages import STATIC_FILES, WS_PATH, HttpPages, is_loopback
from raspv_hmd.tcp_link import TcpLink
from raspv_hmd.websocket_link import WebSocketLink

__all__ = ["CLOSE_TIMEOUT_S", "STATIC_FILES", "WS_PATH", "Callbacks", "ClientStats", "HeadsetServer", "ServerConfig",
           "ServerError", "ServerStats", "is_loopback"]

ANSWERED_REFUSALS = 20              # refused messages each answered with `refused` (beyond: every 10th)
BYE_TIMEOUT_S = 0.5                 # a bye that cannot be written by then (client not reading) is given up


class ServerError(RuntimeError):
    """The server could not start (port in use, bad address, bad TLS files)."""


@dataclass(frozen=True)
class ServerConfig:
    host: str = "127.0.0.1"          # interface to bind; "0.0.0.0" for every IPv4 interface
    port: int = 8765                 # HTTP + WebSocket; 0 picks a free port
    tcp_port: int | None = 8766      # native clients; None: no TCP endpoint; 0 picks a free port
    token: str = ""                  # required from clients when set; generated off-loopback
    compression: str = "auto"        # auto: PNG for remote clients, raw on loopback; png; raw
    deadman_s: float = 0.5           # no teleop input for this long → one zero twist
    hello_timeout_s: float = 5.0
    idle_timeout_s: float = 30.0     # a client silent for this long is dropped
    max_refused: int = 20            # refusals after which a client is dropped
    max_rate: float = 400.0          # messages/s a client may send (bucket of the same size)
    max_clients: int = 16
    tls_cert: str = ""               # PEM files: serve https/wss (needed by WebXR off localhost)
    tls_key: str = ""

    def __post_init__(self) -> None:
        problems = []
        for name in ("port",) + (("tcp_port",) if self.tcp_port is not None else ()):
            v = getattr(self, name)
            if not isinstance(v, int) or not 0 <= v <= 65535:
                problems.append(f"{name} must be an integer in [0, 65535], got {v!r}")
        if self.compression not in ("auto", "png", "raw"):
            problems.append(f"compression must be auto, png or raw, got {self.compression!r}")
        for name in ("deadman_s", "hello_timeout_s", "idle_timeout_s", "max_rate"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                problems.append(f"{name} must be a positive number, got {v!r}")
        if bool(self.tls_cert) != bool(self.tls_key):
            problems.append("tls_cert and tls_key must be given together")
        if problems:
            raise ValueError("; ".join(problems))

    @property
    def loopback(self) -> bool:
        return is_loopback(self.host)


def _noop(*_: Any) -> None:
    return None


@dataclass
class Callbacks:
    """Input from the controlling client, called on the server thread (keep them short)."""

    on_head_orientation: Callable[[tuple[float, float, float, float], float | None], None] = _noop
    on_cmd_vel: Callable[[float, float], None] = _noop          # (m/s, rad/s), base frame
    # (client id, unit direction in the head frame or None when invalid, client time or None, receipt wall time)
    on_gaze: Callable[[int, tuple[float, float, float] | None, float | None, float], None] = _noop
    on_key: Callable[[int, str], None] = _noop                  # (client id, key)
    on_param: Callable[[int, str, Any], None] = _noop           # (client id, name, value)
    on_event: Callable[[str], None] = _noop                     # connection events, for the log
    on_clients: Callable[[], None] = _noop                      # a client came or went (formats may change)
    on_experiment: Callable[[int, str, str], None] = _noop      # (client id, "start"/"abort", instructions id)
    # (composited frames/s, refresh clock [Hz] or None) of the controlling page, about once a second
    on_presented: Callable[[float, float | None], None] = _noop


@dataclass
class ServerStats:
    clients: list[ClientStats]
    connections: int                  # accepted since start
    rejected: dict[str, int]          # refused before or at the hello, by reason
    dropped: dict[str, int]           # clients dropped after the hello, by reason
    refused_total: int                # refused messages of all clients, including gone ones
    frames_submitted: int


class HeadsetServer:
    """Streams phosphene frames to headset clients and hands their input to :class:`Callbacks`."""

    def __init__(self, config: ServerConfig | None = None, callbacks: Callbacks | None = None) -> None:
        self.config = config or ServerConfig()
        self.callbacks = callbacks or Callbacks()
        self.token = self.config.token or ("" if self.config.loopback else secrets.token_urlsafe(12))
        self.port: int | None = None
        self.tcp_port: int | None = None
        self._ssl = self._ssl_context()
        self._sessions: dict[int, ClientSession] = {}
        self._arbiter = ControlArbiter()
        self._deadman = DeadMan(self.config.deadman_s)
        self._deadman_timer: asyncio.TimerHandle | None = None
        self._latest: OutgoingFrame | None = None
        self._latest_levels: LevelsFrame | None = None
        self._sprites: tuple[int, bytes] | None = None     # (map id, sprites message) of the levels stream
        # why the levels stream cannot be sent (then images): until the owner submits sprites, none
        self._levels_unavailable = "no sprites submitted"
        self._instructions = ""                  # the latest experiment instructions (JSON text)
        self._view = ""                          # the display's geometry (JSON text, show_view)
        self._seq = 0
        self._seq_lock = threading.Lock()
        self._png_clients = 0
        self._connections = 0
        self._rejected: collections.Counter[str] = collections.Counter()
        self._http = HttpPages(self.token, lambda: self.port, self._rejected)    # the page, the upgrade's checks
        self._dropped: collections.Counter[str] = collections.Counter()
        self._refused_total = 0
        self._next_id = 1
        self._tasks: set[asyncio.Task] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._start_error: Exception | None = None

    # -- lifecycle ------------------------------------------------------------------------------
    def _ssl_context(self) -> ssl.SSLContext | None:
        if not self.config.tls_cert:
            return None
        ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
        try:
            ctx.load_cert_chain(self.config.tls_cert, self.config.tls_key)
        except (OSError, ssl.SSLError) as exc:
            raise ServerError(f"cannot load the TLS certificate {self.config.tls_cert!r} / key "
                              f"{self.config.tls_key!r}: {exc}") from None
        return ctx

    def start(self) -> "HeadsetServer":
        """Bind the ports and start serving in a background thread (ServerError if impossible)."""
        if self._thread is not None:
            raise ServerError("the server is already running")
        self._thread = threading.Thread(target=self._run, name="hmd-server", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._start_error is not None:
            self._thread.join()
            self._thread = None
            raise self._start_error
        return self

    def stop(self) -> None:
        """Disconnect every client and close the ports; safe to call twice."""
        if self._thread is None:
            return
        if self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(timeout=10)
        self._thread = None

    def __enter__(self) -> "HeadsetServer":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def _run(self) -> None:
        raise_thread_priority(realtime=True, rt_priority=DISPLAY_RT_PRIORITY)   # frames to the headset first (where allowed)
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._main())
        except Exception as exc:  # noqa: BLE001 - reported to start() instead of hanging it
            if not self._ready.is_set():
                self._start_error = ServerError(f"the headset server failed to start: {exc!r}")
            else:
                self._event(f"the headset server stopped on an error: {exc!r}")
        finally:
            self._ready.set()
            loop.close()

    async def _main(self) -> None:
        cfg = self.config
        self._stop = asyncio.Event()
        try:
            ws_server = await serve(self._ws_handler, cfg.host, cfg.port, process_request=self._http.process_request,
                                    compression=None, max_size=HARD_MESSAGE_LIMIT, max_queue=8,
                                    ssl=self._ssl, server_header=None, ping_interval=10, ping_timeout=10,
                                    open_timeout=cfg.hello_timeout_s, close_timeout=CLOSE_TIMEOUT_S)
            tcp_server = None
            if cfg.tcp_port is not None:
                try:
                    tcp_server = await asyncio.start_server(self._tcp_handler, cfg.host, cfg.tcp_port,
                                                            limit=HARD_MESSAGE_LIMIT)
                except OSError:
                    ws_server.close()
                    await ws_server.wait_closed()
                    raise
        except OSError as exc:
            which = f"{cfg.host}:{cfg.port}" + (f" / TCP {cfg.tcp_port}" if cfg.tcp_port is not None else "")
            why = exc.strerror or str(exc)
            hint = " (another program, or another bridge, uses it: choose another port)" if "in use" in why else ""
            self._start_error = ServerError(f"cannot listen on {which}: {why}{hint}")
            self._ready.set()
            return
        self.port = ws_server.sockets[0].getsockname()[1]
        if tcp_server is not None:
            self.tcp_port = tcp_server.sockets[0].getsockname()[1]
        self._ready.set()
        await self._stop.wait()
        for s in list(self._sessions.values()):
            await self._say(s, P.server_message("bye", reason="the server is shutting down"))
        ws_server.close()
        if tcp_server is not None:
            tcp_server.close()
        for s in list(self._sessions.values()):
            await s.link.close()
        if self._tasks:
            await asyncio.wait(set(self._tasks), timeout=5.0)
        try:        # an HTTP client that keeps its socket open must not hold the shutdown up
            await asyncio.wait_for(ws_server.wait_closed(), 1.0)
            if tcp_server is not None:
                await asyncio.wait_for(tcp_server.wait_closed(), 1.0)
        except asyncio.TimeoutError:
            pass
        rest = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        for t in rest:
            t.cancel()
        await asyncio.gather(*rest, return_exceptions=True)

    # -- public, thread-safe --------------------------------------------------------------------
    def urls(self) -> list[str]:
        """Where to open the client page (with the token when one is needed)."""
        return [page for page, _ in self.endpoints()]

    def endpoints(self) -> list[tuple[str, str | None]]:
        """(page URL, native TCP endpoint or None) for each address the server is reachable at."""
        scheme = "https" if self._ssl else "http"
        hosts = [self.config.host]
        if self.config.host in ("0.0.0.0", "", "::"):
            hosts = _interface_addresses() or ["127.0.0.1"]
        query = f"?token={self.token}" if self.token else ""
        out = []
        for h in hosts:
            name = f"[{h}]" if ":" in h else h
            tcp = f"tcp://{name}:{self.tcp_port}" if self.tcp_port else None
            out.append((f"{scheme}://{name}:{self.port}/{query}", tcp))
        return out

    def submit_frame(self, image: np.ndarray, stamp: float) -> int:
        """Offer a phosphene image ((H, W) mono8 or (H, W, 3) rgb8; ``stamp`` = its time, s) to
        every client; returns its sequence number. Replaces any frame not yet sent."""
        with self._seq_lock:
            self._seq += 1
            seq = self._seq
        frame = OutgoingFrame(seq, image, stamp)
        if self._png_clients > 0:
            frame.payload(P.FORMAT_PNG)          # encode here, off the server thread
        self._call_soon(self._new_frame, frame)
        return seq

    def submit_sprites(self, map_id: int, message: bytes) -> None:
        """The sprite atlas of map ``map_id`` (:meth:`raspv_hmd.levels_stream.SpriteAtlas.message`)
        for levels clients; sent to each before its first frame of that map."""
        self._call_soon(self._set_sprites, (map_id, message), "")

    def levels_unavailable(self, reason: str) -> None:
        """The levels stream cannot be drawn (e.g. the sprites exceed a texture): levels clients
        get images until the next :meth:`submit_sprites`, and are told ``reason``."""
        self._call_soon(self._set_sprites, None, reason)

    def submit_levels(self, map_id: int, payload: bytes, stamp: float, width: int, height: int,
                      green: bool = False) -> int:
        """Offer one frame as a levels payload (:func:`raspv_hmd.levels_stream.pack_levels_payload`)
        to levels clients; returns its sequence number. Replaces any frame not yet sent."""
        with self._seq_lock:
            self._seq += 1
            seq = self._seq
        self._call_soon(self._new_levels, LevelsFrame(seq, map_id, payload, stamp, width, height, green))
        return seq

    @property
    def wants_images(self) -> bool:
        """Some client needs phosphene images (it asked for raw/png, or levels cannot be sent)."""
        return any(s.format != P.FORMAT_LEVELS or self._levels_unavailable for s in list(self._sessions.values()))

    @property
    def wants_levels(self) -> bool:
        """Some client draws the levels stream."""
        return any(s.format == P.FORMAT_LEVELS for s in list(self._sessions.values()))

    def _call_soon(self, fn: Callable[..., None], *args: Any) -> None:
        loop = self._loop
        if loop is not None and self._ready.is_set() and self._start_error is None:
            try:
                loop.call_soon_threadsafe(fn, *args)
            except RuntimeError:                  # the loop is closing
                pass

    def notify(self, text: str, ok: bool = True, client: int | None = None) -> None:
        """Send a status line to one client (by id) or to all (``None``)."""
        self._send(P.server_message("status", text=text, ok=ok), client)

    def show_instructions(self, info: dict[str, Any] | None) -> None:
        """Experiment instructions for every client (and clients that connect later), or None
        to hide them: ``{"id", "title", "text", "waiting"}`` (waiting: a start is expected)."""
        self._instructions = P.server_message("instructions", **(info or {"id": "", "text": "", "waiting": False}))
        self._send(self._instructions)

    def show_view(self, **fields: Any) -> None:
        """The phosphene display's geometry for every client (and later ones): ``width``, ``height``
        [px], ``focal_px`` (f_P of K_P), ``spacing_px`` — what a client needs to turn a point on
        the display into a gaze direction (the browser's mouse gaze and calibration targets)."""
        self._view = P.server_message("view", **fields)
        self._send(self._view)

    def broadcast(self, kind: str, **fields: Any) -> None:
        """Send a JSON message of type ``kind`` to every client (e.g. the audio ``cues``)."""
        self._send(P.server_message(kind, **fields))

    def _send(self, msg: Any, client: int | None = None) -> None:
        """Queue ``msg`` on the server loop for one client (by id) or for all (``None``)."""
        loop = self._loop
        if loop is None:
            return

        def send() -> None:
            for s in list(self._sessions.values()):
                if client is None or s.id == client:
                    loop.create_task(self._say(s, msg))
        try:
            loop.call_soon_threadsafe(send)
        except RuntimeError:
            pass

    @property
    def controller(self) -> int | None:
        return self._arbiter.controller

    def stats(self, timeout: float = 2.0) -> ServerStats:
        """A consistent snapshot of the counters (taken on the server thread)."""
        loop = self._loop
        if loop is None or not loop.is_running():
            return self._stats()
        fut = asyncio.run_coroutine_threadsafe(self._async_stats(), loop)
        return fut.result(timeout)

    async def _async_stats(self) -> ServerStats:
        return self._stats()

    def _stats(self) -> ServerStats:
        ctl = self._arbiter.controller
        return ServerStats([s.stats("control" if s.id == ctl else "watch") for s in self._sessions.values()],
                           self._connections, dict(self._rejected), dict(self._dropped), self._refused_total,
                           self._seq)

    # -- frames ---------------------------------------------------------------------------------
    def _new_frame(self, frame: OutgoingFrame) -> None:
        if self._latest is not None and frame.seq < self._latest.seq:
            return
        self._latest = frame
        for s in self._sessions.values():
            if s.format != P.FORMAT_LEVELS or self._levels_unavailable:
                s.frame_ready.set()

    def _new_levels(self, frame: "LevelsFrame") -> None:
        if self._latest_levels is not None and frame.seq < self._latest_levels.seq:
            return
        self._latest_levels = frame
        for s in self._sessions.values():
            if s.format == P.FORMAT_LEVELS:
                s.frame_ready.set()

    def _set_sprites(self, sprites: tuple[int, bytes] | None, reason: str) -> None:
        was = self._levels_unavailable
        self._sprites, self._levels_unavailable = sprites, reason
        if reason and reason != was:
            self._event(f"levels stream unavailable ({reason}): levels clients get images")
            for s in self._sessions.values():
                if s.format == P.FORMAT_LEVELS:
                    self._send(P.server_message("status", ok=False, text=f"images instead of levels: {reason}"), s.id)

    def _next_for(self, s: ClientSession) -> tuple[int, Any] | None:
        """(format, frame) this client gets next: a levels frame whose sprites it has (or can get
        now), else the newest image."""
        if s.format == P.FORMAT_LEVELS and not self._levels_unavailable:
            frame = self._latest_levels
            if frame is None or self._sprites is None or self._sprites[0] != frame.map_id:
                return None                       # its sprites are not in yet: nothing to draw with
            return P.FORMAT_LEVELS, frame
        return (s.image_format if s.format == P.FORMAT_LEVELS else s.format), self._latest

    async def _sender(self, s: ClientSession) -> None:
        while True:
            await s.frame_ready.wait()
            s.frame_ready.clear()
            while s.window and len(s.in_flight) >= s.window:
                s.acked.clear()
                await s.acked.wait()
            picked = self._next_for(s)
            if picked is None or picked[1] is None or picked[1].seq <= s.last_sent:
                continue
            fmt, frame = picked
            if fmt == P.FORMAT_LEVELS and s.sprites_sent != frame.map_id:
                await s.link.send_frame(self._sprites[1])     # the atlas first (once per map)
                s.sprites_sent = frame.map_id
            if s.last_sent and fmt == s.format:
                s.frames_skipped += frame.seq - s.last_sent - 1
            _, data = frame.message(fmt, time.time())
            s.last_sent = frame.seq
            if s.window:
                s.in_flight.append((frame.seq, time.monotonic()))
            await s.link.send_frame(data)
            s.frames_sent += 1

    # -- connections ----------------------------------------------------------------------------
    async def _ws_handler(self, ws: ServerConnection) -> None:
        query = parse_qs(urlsplit(ws.request.path).query) if ws.request else {}
        peer = ws.remote_address
        await self._serve_client(WebSocketLink(ws), peer, query.get("token", [""])[0])

    async def _tcp_handler(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        await self._serve_client(TcpLink(reader, writer), writer.get_extra_info("peername"), "")

    async def _serve_client(self, link: Link, peer: Any, url_token: str) -> None:
        task = asyncio.current_task()
        self._tasks.add(task)
        try:
            await self._serve_client_until_gone(link, peer, url_token)
        finally:
            self._tasks.discard(task)

    async def _serve_client_until_gone(self, link: Link, peer: Any, url_token: str) -> None:
        peer_host = peer[0] if isinstance(peer, tuple) and peer else str(peer)
        peer_text = f"{peer_host}:{peer[1]}" if isinstance(peer, tuple) and len(peer) > 1 else peer_host
        hello = await self._handshake(link, peer_text, url_token)
        if hello is None:
            await link.close()
            return
        cid, self._next_id = self._next_id, self._next_id + 1
        s = ClientSession(cid, link, peer_text, not is_loopback(peer_host), hello, self.config.compression,
                     self.config.max_rate)
        s.task = asyncio.current_task()
        self._sessions[cid] = s
        self._connections += 1
        self._png_clients += s.format == P.FORMAT_PNG
        changed = self._arbiter.add(cid, hello.role == "control")
        role = "control" if self._arbiter.controller == cid else "watch"
        await self._say(s, P.server_message(
            "welcome", protocol=P.PROTOCOL_VERSION, client_id=cid, role=role, format=P.FORMAT_NAMES[s.format],
            window=s.window, server_time=time.time(), deadman_s=self.config.deadman_s,
            limits={"message_bytes": P.MAX_CLIENT_MESSAGE, "rate": self.config.max_rate,
                    "max_refused": self.config.max_refused, "idle_s": self.config.idle_timeout_s}))
        self._call(self.callbacks.on_clients)
        self._event(f"{link.transport} client {cid} '{s.name}' from {peer_text} connected ({role}, "
                    f"{P.FORMAT_NAMES[s.format]} frames)")
        if changed:
            await self._announce_roles()
        if self._instructions:
            await self._say(s, self._instructions)
        if self._view:
            await self._say(s, self._view)
        if self._latest is not None or self._latest_levels is not None:
            s.frame_ready.set()
        sender = asyncio.create_task(self._sender(s))
        reason = "left"
        try:
            reason = await self._receive_loop(s)
        except Drop as exc:
            if exc.code == "oversized":          # the message that broke the limit is a refusal too
                s.refused[exc.code] += 1
                self._refused_total += 1
            reason = f"dropped: {exc}"
            self._dropped[exc.code] += 1
            if exc.code != "abuse":              # abuse: _refuse said bye already
                await self._send_bye(link, f"dropped: {exc}")
        except (ConnectionError, ConnectionClosed):
            reason = "connection lost"
        except asyncio.CancelledError:
            if s.evicted is None:
                raise
            reason = s.evicted
        finally:
            if s.evicted is not None:
                reason = s.evicted
            sender.cancel()
            try:
                await sender
            except (asyncio.CancelledError, ConnectionError, ConnectionClosed):
                pass
            except Exception as exc:  # noqa: BLE001 - a failed send ends only this client
                reason = f"send failed: {exc!r}"
            self._sessions.pop(cid, None)
            self._png_clients -= s.format == P.FORMAT_PNG
            was_controller = self._arbiter.controller == cid
            changed = self._arbiter.remove(cid)
            if was_controller and self._deadman.release():
                self._call(self.callbacks.on_cmd_vel, 0.0, 0.0)
            await link.close()
            self._call(self.callbacks.on_clients)
            self._event(f"client {cid} '{s.name}' {reason} (received {s.received}, refused "
                        f"{sum(s.refused.values())}, frames sent {s.frames_sent})")
            if changed:
                await self._announce_roles()

    async def _handshake(self, link: Link, peer: str, url_token: str) -> P.Hello | None:
        try:
            first = await asyncio.wait_for(link.recv(), self.config.hello_timeout_s)
        except asyncio.TimeoutError:
            return await self._reject("hello_timeout", peer, f"no hello within {self.config.hello_timeout_s:g} s", link)
        except (Drop, P.ProtocolError) as exc:
            return await self._reject(getattr(exc, "code", "bad_hello"), peer, str(exc), link)
        except (ConnectionError, ConnectionClosed):
            return None
        if first is None:
            return None
        try:
            hello = P.parse_client_message(first)
        except P.ProtocolError as exc:
            return await self._reject(exc.code, peer, f"bad hello: {exc}", link)
        if not isinstance(hello, P.Hello):
            return await self._reject("no_hello", peer, "the first message must be a hello", link)
        if self.token:
            given = hello.token or url_token
            if not hmac.compare_digest(given.encode(), self.token.encode()):
                return await self._reject("token", peer, "wrong or missing token", link)
        if len(self._sessions) >= self.config.max_clients and not await self._make_room(hello, peer):
            why = f"the server is full ({self.config.max_clients} clients)"
            if hello.role == "control":
                why += ", each controlling or in line for control"
            return await self._reject("full", peer, why, link)
        return hello

    async def _make_room(self, hello: P.Hello, peer: str) -> bool:
        """Room for a newcomer that wants control, when the server is full: a watcher (a client
        that neither controls nor wants control) is evicted, the one least recently active
        first. Clients that want control are in line for it and keep their place: when every
        slot holds one, the newcomer is refused. A watcher evicts nobody. True when a slot is
        free now."""
        if hello.role != "control":
            return False
        ctl = self._arbiter.controller
        watchers = [s for s in self._sessions.values() if s.id != ctl and not s.wants_control and s.evicted is None]
        if not watchers:
            return False
        victim = min(watchers, key=lambda s: (s.last_active, s.id))
        why = (f"evicted: the server was full ({self.config.max_clients} clients) and a client that wants "
               f"control ({hello.name or peer}) needed a watcher's slot")
        victim.evicted = why               # logged once, by its own loop as it ends (with its counts)
        self._dropped["evicted"] += 1
        await self._send_bye(victim.link, why)
        await victim.link.close()
        if victim.task is not None:        # its own loop removes it from the sessions
            done, _ = await asyncio.wait({victim.task}, timeout=CLOSE_TIMEOUT_S + 1.0)
            if not done:
                victim.task.cancel()
        self._sessions.pop(victim.id, None)
        return len(self._sessions) < self.config.max_clients

    async def _reject(self, code: str, peer: str, why: str, link: Link | None = None) -> None:
        """Count and log a refused connection, telling the client why when it can still listen."""
        self._rejected[code] += 1
        self._event(f"refused a client from {peer}: {why}")
        if link is not None:
            await self._send_bye(link, why)
        return None

    async def _send_bye(self, link: Link, reason: str) -> None:
        link.said_bye = True
        try:
            await asyncio.wait_for(link.send_text(P.server_message("bye", reason=reason)), BYE_TIMEOUT_S)
        except (ConnectionError, ConnectionClosed, asyncio.TimeoutError):
            pass

    async def _receive_loop(self, s: ClientSession) -> str:
        cfg = self.config
        while True:
            try:
                raw = await asyncio.wait_for(s.link.recv(), cfg.idle_timeout_s)
            except asyncio.TimeoutError:
                raise Drop("idle", f"silent for {cfg.idle_timeout_s:g} s") from None
            except P.ProtocolError as exc:
                await self._refuse(s, exc)
                continue
            if raw is None:
                return "left"
            if s.evicted is not None:            # told to go, and still sending: not listening
                s.link.cut()
                return s.evicted
            s.received += 1
            if not s.take_token(time.monotonic()):
                await self._refuse(s, P.ProtocolError("rate", f"more than {cfg.max_rate:g} messages/s"))
                continue
            try:
                msg = P.parse_client_message(raw)
                await self._dispatch(s, msg)
            except P.ProtocolError as exc:
                await self._refuse(s, exc)

    async def _refuse(self, s: ClientSession, exc: P.ProtocolError) -> None:
        s.refused[exc.code] += 1
        self._refused_total += 1
        total = sum(s.refused.values())
        if total >= self.config.max_refused:
            await self._send_bye(s.link, f"{total} refused messages; last: {exc}")
            raise Drop("abuse", f"{total} refused messages (last: {exc.code}: {exc})")
        if total <= ANSWERED_REFUSALS or total % 10 == 0:      # one each; a flood beyond: every 10th
            await self._say(s, P.server_message("refused", code=exc.code, reason=str(exc), count=total))

    async def _dispatch(self, s: ClientSession, msg: P.ClientMessage) -> None:
        if isinstance(msg, P.Ping):
            await self._say(s, P.server_message("pong", t=msg.t, server_time=time.time()))
            return
        if isinstance(msg, P.Ack):
            if msg.seq > s.last_sent:
                raise P.ProtocolError("bad_field", f"ack of frame {msg.seq}, which was not sent (last {s.last_sent})")
            now = time.monotonic()
            while s.in_flight and s.in_flight[0][0] <= msg.seq:
                seq, sent = s.in_flight.popleft()
                if seq == msg.seq:
                    s.ack_rtts.append(1e3 * (now - sent))
            s.acked.set()
            return
        if isinstance(msg, P.Control):
            s.wants_control = msg.want
            if self._arbiter.set_want(s.id, msg.want):
                if self._deadman.release():
                    self._call(self.callbacks.on_cmd_vel, 0.0, 0.0)
                await self._announce_roles()
            return
        if isinstance(msg, P.Hello):
            raise P.ProtocolError("bad_field", "hello was already received")
        if isinstance(msg, P.Presented):          # only the wearer's page judges the display rate; others' are dropped
            if self._arbiter.controller == s.id:
                self._call(self.callbacks.on_presented, msg.fps, msg.refresh_hz)
            return
        s.last_active = time.monotonic()
        if self._arbiter.controller != s.id:
            s.ignored += 1
            if s.ignored == 1:
                await self._say(s, P.server_message("status", ok=False,
                                                    text="watching: another client controls the avatar"))
            return
        if isinstance(msg, P.Head):
            self._call(self.callbacks.on_head_orientation, msg.quaternion, msg.client_time)
        elif isinstance(msg, P.Gaze):
            self._call(self.callbacks.on_gaze, s.id, msg.direction, msg.client_time, time.time())
        elif isinstance(msg, P.Twist):
            self._deadman.input(msg.linear, msg.angular, time.monotonic())
            self._call(self.callbacks.on_cmd_vel, msg.linear, msg.angular)
            self._arm_deadman()
        elif isinstance(msg, P.Key):
            self._call(self.callbacks.on_key, s.id, msg.key)
        elif isinstance(msg, P.SetParam):
            self._call(self.callbacks.on_param, s.id, msg.name, msg.value)
        elif isinstance(msg, P.Experiment):
            self._call(self.callbacks.on_experiment, s.id, msg.action, msg.id)

    # -- helpers --------------------------------------------------------------------------------
    def _arm_deadman(self) -> None:
        if self._deadman_timer is not None:
            self._deadman_timer.cancel()
            self._deadman_timer = None
        due = self._deadman.deadline()
        if due is not None:
            self._deadman_timer = asyncio.get_running_loop().call_later(
                max(0.0, due - time.monotonic()), self._deadman_fire)

    def _deadman_fire(self) -> None:
        self._deadman_timer = None
        if self._deadman.poll(time.monotonic()):
            self._call(self.callbacks.on_cmd_vel, 0.0, 0.0)
            self._event(f"no teleop input for {self.config.deadman_s:g} s: stopped the avatar")
        else:
            self._arm_deadman()

    async def _announce_roles(self) -> None:
        ctl = self._arbiter.controller
        for s in list(self._sessions.values()):
            await self._say(s, P.server_message("role", role="control" if s.id == ctl else "watch", controller=ctl))

    async def _say(self, s: ClientSession, text: str) -> None:
        try:
            await asyncio.wait_for(s.link.send_text(text), 5.0)
        except (ConnectionError, ConnectionClosed, asyncio.TimeoutError):
            pass

    def _call(self, fn: Callable[..., None], *args: Any) -> None:
        try:
            fn(*args)
        except Exception as exc:  # noqa: BLE001 - a failing owner callback must not stop the server
            self._event(f"callback {getattr(fn, '__name__', fn)} failed: {exc!r}")

    def _event(self, text: str) -> None:
        try:
            self.callbacks.on_event(text)
        except Exception:  # noqa: BLE001 - logging must never break serving
            pass


def _interface_addresses() -> list[str]:
    import socket

    import psutil

    out = []
    for addrs in psutil.net_if_addrs().values():
        for a in addrs:
            if a.family == socket.AF_INET and not a.address.startswith("127."):
                out.append(a.address)
    return out
