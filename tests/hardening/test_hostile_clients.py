"""Hostile-but-fair clients against the headset server core on loopback (issues 16 and 27):
slot exhaustion and the line for control, a `bye` on every refusal, a prompt close after
refusal (also of a client that keeps sending), slots freed at once, an empty key refused.
Every loop is bounded; the timeouts below are failure bounds, not measurements."""
from __future__ import annotations

import asyncio
import base64
import os
import time

import pytest
from websockets.exceptions import ConnectionClosed
from websockets.frames import Frame, Opcode

from raspv_hmd import protocol as P
from raspv_hmd.keymap import key_change
from raspv_hmd.server import CLOSE_TIMEOUT_S

from .conftest import TcpClient, ws_connect, ws_hello, ws_next_json

WS_CLOSE_LINGER_S = 10.0      # what a client that stops reading used to cost (websockets' default close_timeout)


def test_a_controlling_headset_gets_a_watchers_slot(start_server, server_events):
    """A controller and 15 watchers that only ping hold every slot; a headset that wants control
    still gets in (the least recently active watcher is evicted with a `bye` saying why); a
    watcher arriving then is refused."""
    server = start_server(max_clients=16)

    async def run():
        controller, _ = await ws_hello(server, name="controller")
        pingers = []
        for i in range(15):
            ws, welcome = await ws_hello(server, name=f"pinger {i}", role="watch")
            assert welcome["type"] == "welcome"
            pingers.append(ws)
        for i, ws in enumerate(pingers):
            await ws.send(P.client_message("ping", t=i))
            await ws_next_json(ws, "pong")
        headset, welcome = await ws_hello(server, name="headset", role="control")
        assert welcome["type"] == "welcome", welcome
        names = [c.name for c in server.stats().clients]
        assert len(names) == 16 and "headset" in names and "controller" in names
        assert "pinger 0" not in names            # none sent control input: the earliest goes
        bye = await ws_next_json(pingers[0], "bye")
        assert "evicted" in bye["reason"] and "control" in bye["reason"]
        # a passive watcher never evicts anyone: the server is full for it
        watcher, answer = await ws_hello(server, name="watcher", role="watch")
        assert answer["type"] == "bye" and "full" in answer["reason"]
        for ws in [controller, *pingers, headset, watcher]:
            await ws.close()

    asyncio.run(run())
    evictions = [e for e in server_events if "evicted" in e]
    assert len(evictions) == 1 and "received" in evictions[0], evictions     # once, with its counts (issue 36)


def test_each_refused_message_is_answered_before_the_bye(start_server):
    """20 malformed messages of five kinds: a `refused` for each of the first 19, then the 20th
    reaches max_refused and is answered by the `bye` (issue 36: 15 replies, one per kind up to 3)."""
    server = start_server(max_refused=20)
    bad = ["not json", "[1, 2]", '{"type": "teleport"}', '{"type": "key", "key": ""}', '{"type": "ack", "seq": 99}']

    async def run():
        ws, welcome = await ws_hello(server, name="sloppy", role="watch")
        assert welcome["type"] == "welcome"
        for i in range(20):
            await ws.send(bad[i % len(bad)])
        answers = []
        while not answers or answers[-1]["type"] != "bye":
            answers.append(await ws_next_json(ws))
        refused = [a for a in answers if a["type"] == "refused"]
        assert [a["count"] for a in refused] == list(range(1, 20)), answers
        assert "20 refused messages" in answers[-1]["reason"]
        await ws.close()

    asyncio.run(run())


def test_clients_in_line_for_control_keep_their_place(start_server):
    """20 clients that want control and 16 slots: clients 17-20 are refused (`bye`: full), never
    clients 1-16, who are next in line; when the controller leaves, client 2 controls."""
    server = start_server(max_clients=16)

    async def run():
        clients, answers = [], []
        for i in range(1, 21):
            ws, answer = await ws_hello(server, name=f"client {i}", role="control")
            clients.append(ws)
            answers.append(answer)
        assert [a["type"] for a in answers] == ["welcome"] * 16 + ["bye"] * 4, answers
        assert all("full" in a["reason"] and "in line for control" in a["reason"] for a in answers[16:])
        stats = server.stats()
        assert sorted(c.name for c in stats.clients) == sorted(f"client {i}" for i in range(1, 17))
        assert stats.dropped.get("evicted", 0) == 0 and stats.rejected == {"full": 4}
        await clients[0].close()
        role = await ws_next_json(clients[1], "role")
        while role["role"] != "control":
            role = await ws_next_json(clients[1], "role")
        for ws in clients:
            await ws.close()

    asyncio.run(run())


def test_a_watcher_is_evicted_before_a_client_waiting_for_control(start_server):
    server = start_server(max_clients=3)

    async def run():
        first, _ = await ws_hello(server, name="controller")
        waiting, _ = await ws_hello(server, name="waiting", role="control")
        watcher, _ = await ws_hello(server, name="watcher", role="watch")
        headset, welcome = await ws_hello(server, name="headset")
        assert welcome["type"] == "welcome"
        assert (await ws_next_json(watcher, "bye"))["reason"].startswith("evicted")
        assert sorted(c.name for c in server.stats().clients) == ["controller", "headset", "waiting"]
        for ws in (first, waiting, watcher, headset):
            await ws.close()

    asyncio.run(run())


def test_every_refusal_says_bye(start_server):
    """Whatever the reason a connection is refused, the client is told why before the close."""
    server = start_server(max_clients=1, hello_timeout_s=0.3, token="secret")

    async def run():
        ws = await ws_connect(server)
        await ws.send(b"\x00\x01 a binary hello")
        assert "JSON text" in (await ws_next_json(ws, "bye"))["reason"]
        await _ws_closed(ws)
        ws = await ws_connect(server)                         # silent: no hello in time
        assert "no hello" in (await ws_next_json(ws, "bye"))["reason"]
        await _ws_closed(ws)
        ws, bye = await ws_hello(server, token="wrong")
        assert bye["type"] == "bye" and "token" in bye["reason"]
        await _ws_closed(ws)
        tcp = await TcpClient.open(server)
        await tcp.send(b"\x00binary", kind=P.TCP_FRAME)         # a frame-kind message as hello
        assert "JSON" in (await tcp.next_json("bye"))["reason"]
        assert await tcp.closed_by_server(5.0)
        tcp = await TcpClient.open(server)
        tcp.writer.write(P.TCP_HEADER.pack(10_000_000, P.TCP_JSON))   # announces 10 MB
        assert "limit" in (await tcp.next_json("bye"))["reason"]
        assert await tcp.closed_by_server(5.0)
        first, welcome = await ws_hello(server, token="secret")
        assert welcome["type"] == "welcome"
        second, bye = await ws_hello(server, token="secret", role="watch")
        assert bye["type"] == "bye" and "full" in bye["reason"]
        await second.close()
        await first.close()

    asyncio.run(run())
    rejected = server.stats().rejected
    assert rejected == {"binary": 1, "hello_timeout": 1, "token": 1, "bad_kind": 1, "oversized": 1, "full": 1}, rejected


async def _raw_ws(server, first: bytes | str):
    """A raw WebSocket client that never answers a closing handshake; sends ``first``."""
    reader, writer = await asyncio.open_connection("127.0.0.1", server.port)
    key = base64.b64encode(os.urandom(16)).decode()
    writer.write((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{server.port}\r\nUpgrade: websocket\r\n"
                  f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
    await writer.drain()
    assert b" 101 " in await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), 5.0)
    opcode = Opcode.TEXT if isinstance(first, str) else Opcode.BINARY
    writer.write(Frame(opcode, first.encode() if isinstance(first, str) else first).serialize(mask=True))
    await writer.drain()
    return reader, writer


async def _keep_sending_until_closed(reader, writer, bound_s: float) -> tuple[bytes, float]:
    """Send a ping every 10 ms while reading; (everything read, seconds from the `bye` to the
    server's close)."""
    async def pinger():
        while True:
            writer.write(Frame(Opcode.TEXT, P.client_message("ping", t=1).encode()).serialize(mask=True))
            await writer.drain()
            await asyncio.sleep(0.01)

    task = asyncio.create_task(pinger())
    data, t_bye = b"", None
    try:
        while chunk := await asyncio.wait_for(reader.read(65536), bound_s):
            data += chunk
            if t_bye is None and b'"type":"bye"' in data:
                t_bye = time.monotonic()
    except (ConnectionError, asyncio.TimeoutError):
        pass
    closed = time.monotonic()
    task.cancel()
    writer.close()
    assert t_bye is not None, data[-300:]
    return data, closed - t_bye


def test_a_client_that_keeps_sending_after_its_bye_is_closed_at_once(start_server):
    """A refused hello, a drop for refused messages, an eviction: the client is told why, goes on
    sending instead of answering the closing handshake, and the server closes the connection at
    once — not after its closing-handshake timeout (1 s). The bounds are failure bounds."""
    server = start_server(max_clients=2, max_refused=5)

    async def run():
        reader, writer = await _raw_ws(server, b"\x00 a binary hello")
        data, after = await _keep_sending_until_closed(reader, writer, 5.0)
        assert b"JSON text" in data and after < CLOSE_TIMEOUT_S / 2, after
        reader, writer = await _raw_ws(server, P.client_message("hello", name="flooder", role="watch"))
        for _ in range(5):
            writer.write(Frame(Opcode.TEXT, b"junk").serialize(mask=True))
        data, after = await _keep_sending_until_closed(reader, writer, 5.0)
        assert b"refused" in data and after < CLOSE_TIMEOUT_S / 2, after
        controller, _ = await ws_hello(server, name="controller")
        reader, writer = await _raw_ws(server, P.client_message("hello", name="watcher", role="watch"))
        evicting = asyncio.create_task(ws_hello(server, name="headset"))
        data, after = await _keep_sending_until_closed(reader, writer, 5.0)
        assert b"evicted" in data and after < CLOSE_TIMEOUT_S / 2, after
        headset, welcome = await evicting
        assert welcome["type"] == "welcome"
        await headset.close()
        await controller.close()

    asyncio.run(run())


def test_an_empty_key_is_a_protocol_error_with_its_reason(start_server, server_events):
    server = start_server()

    async def run():
        ws, _ = await ws_hello(server, name="keys")
        await ws.send(P.client_message("key", key=""))
        refused = await ws_next_json(ws, "refused")
        assert refused["code"] == "bad_field" and "'key' must name a key" in refused["reason"]
        await ws.close()

    asyncio.run(run())
    assert not any("invalid literal" in e for e in server_events), server_events
    for key in ("", "12"):                     # no mode key either (the key map's own guard)
        with pytest.raises(KeyError):
            key_change(key, {"mode": "depth"}, ["depth", "edges"])


def test_a_client_dropped_for_refused_messages_is_closed_promptly_even_if_it_stops_reading(start_server):
    """20 refused messages from a client that reads nothing: the server says bye and closes the
    TCP connection itself instead of waiting for a closing handshake that never comes."""
    server = start_server(max_refused=20)

    async def run():
        reader, writer = await _raw_ws(server, P.client_message("hello", name="flooder"))
        for _ in range(20):
            writer.write(Frame(Opcode.TEXT, b"junk").serialize(mask=True))
        await writer.drain()
        # never answer the server's close frame: only the server can end the connection now
        data = b""
        try:
            while chunk := await asyncio.wait_for(reader.read(65536), WS_CLOSE_LINGER_S / 2):
                data += chunk
        except ConnectionError:
            pass
        assert b'"type":"bye"' in data and b"refused" in data
        writer.close()

    asyncio.run(run())
    assert server.stats().dropped == {"abuse": 1}


def test_tcp_client_that_stops_reading_is_closed_promptly_after_its_refusals(start_server):
    server = start_server(max_refused=20)

    async def run():
        tcp = await TcpClient.open(server)
        await tcp.send(P.client_message("hello", name="flooder", role="watch"))
        try:
            for _ in range(25):
                await tcp.send("junk")
        except ConnectionError:
            return                      # closed by the server after the 20th refusal, before our 25th
        assert await tcp.closed_by_server(WS_CLOSE_LINGER_S / 2)

    asyncio.run(run())
    assert server.stats().dropped == {"abuse": 1}


def test_slots_are_freed_as_soon_as_clients_leave(start_server):
    server = start_server(max_clients=2)

    async def run():
        for _ in range(5):                          # politely, then abruptly (TCP reset), 5 times over
            a, _ = await ws_hello(server, name="a")
            b = await TcpClient.open(server)
            await b.send(P.client_message("hello", name="b"))
            assert (await b.next_json())["type"] == "welcome"
            await a.close()
            b.writer.transport.abort()
            c, welcome = await ws_hello(server, name="c", role="watch")   # a watcher evicts nobody
            d, welcome2 = await ws_hello(server, name="d", role="watch")
            assert welcome["type"] == welcome2["type"] == "welcome", (welcome, welcome2)
            await c.close()
            await d.close()
            await _wait_empty(server)

    asyncio.run(run())


async def _ws_closed(ws, timeout: float = 5.0) -> None:
    try:
        while True:
            await asyncio.wait_for(ws.recv(), timeout)
    except ConnectionClosed:
        return


async def _wait_empty(server, bound: int = 500) -> None:
    for _ in range(bound):
        if not server.stats().clients:
            return
        await asyncio.sleep(0.01)
    raise AssertionError(f"clients still connected: {server.stats().clients}")
