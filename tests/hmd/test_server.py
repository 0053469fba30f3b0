"""The headset server core on real sockets: page and assets, roles, refusals and drops, tokens,
the dead-man, stale-frame skipping, the TCP endpoint, TLS."""
from __future__ import annotations

import asyncio
import http.client
import json
import shutil
import ssl
import subprocess
import time
import urllib.request

import numpy as np
import pytest
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidStatus

from raspv_hmd import protocol as P
from raspv_hmd.server import ServerError

FRAME = np.zeros((30, 40), np.uint8)
FRAME[10:20, 10:30] = 200


# -- client helpers -----------------------------------------------------------------------------
async def open_ws(server, headers=None, scheme="ws", ssl_context=None, **hello):
    # max_queue=None: a test that stops reading must not stall the closing handshake behind
    # unread messages (websockets pauses reading when its queue is full)
    ws = await connect(f"{scheme}://127.0.0.1:{server.port}/ws", max_size=None, compression=None,
                       additional_headers=headers, ssl=ssl_context, max_queue=None)
    await ws.send(P.client_message("hello", **hello))
    return ws, await next_json(ws)


async def next_json(ws, kind=None, timeout=5.0):
    while True:
        msg = await asyncio.wait_for(ws.recv(), timeout)
        if isinstance(msg, str):
            m = json.loads(msg)
            if kind is None or m["type"] == kind:
                return m


async def next_frame(ws, timeout=5.0):
    while True:
        msg = await asyncio.wait_for(ws.recv(), timeout)
        if isinstance(msg, bytes):
            return P.unpack_frame(msg)


async def closed(ws, timeout=5.0) -> bool:
    try:
        while True:
            await asyncio.wait_for(ws.recv(), timeout)
    except ConnectionClosed:
        return True


class Tcp:
    def __init__(self, reader, writer):
        self.reader, self.writer = reader, writer

    @classmethod
    async def open(cls, server):
        return cls(*await asyncio.open_connection("127.0.0.1", server.tcp_port))

    async def send(self, text: str, kind: int = P.TCP_JSON, length: int | None = None):
        data = text.encode()
        self.writer.write(P.TCP_HEADER.pack(len(data) if length is None else length, kind) + data)
        await self.writer.drain()

    async def recv(self, timeout=5.0):
        n, kind = P.TCP_HEADER.unpack(await asyncio.wait_for(self.reader.readexactly(5), timeout))
        return kind, await asyncio.wait_for(self.reader.readexactly(n), timeout)

    async def next_json(self, kind=None):
        while True:
            k, data = await self.recv()
            if k == P.TCP_JSON:
                m = json.loads(data)
                if kind is None or m["type"] == kind:
                    return m

    async def close(self):
        self.writer.close()


async def keep_submitting(server):
    """Submit a frame every 20 ms until cancelled."""
    while True:
        server.submit_frame(FRAME, time.time())
        await asyncio.sleep(0.02)


# -- HTTP ---------------------------------------------------------------------------------------
def test_page_and_assets_are_served_on_the_websocket_port(start_server):
    server = start_server()
    base = f"http://127.0.0.1:{server.port}"
    with urllib.request.urlopen(base + "/") as r:
        page = r.read().decode()
        assert r.headers["Content-Type"].startswith("text/html")
        assert "default-src 'self'" in r.headers["Content-Security-Policy"]
    assert '<script src="client.js">' in page and "<canvas" in page
    with urllib.request.urlopen(base + "/client.js") as r:
        assert r.headers["Content-Type"].startswith("text/javascript")
        assert b"raspvClient" in r.read()
    with urllib.request.urlopen(base + "/style.css") as r:
        assert r.status == 200
    with pytest.raises(urllib.error.HTTPError) as err:
        urllib.request.urlopen(base + "/etc/passwd")
    assert err.value.code == 404
    err.value.close()


def test_loopback_server_refuses_foreign_host_names_and_origins(start_server):
    server = start_server()
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=5)
    conn.request("GET", "/", headers={"Host": f"attacker.example:{server.port}"})   # DNS rebinding
    r = conn.getresponse()
    assert r.status == 403 and b"loopback" in r.read()
    conn.close()

    async def run():
        with pytest.raises(InvalidStatus) as err:
            await open_ws(server, headers={"Origin": "http://attacker.example"})
        assert err.value.response.status_code == 403
        ws, welcome = await open_ws(server, headers={"Origin": f"http://127.0.0.1:{server.port}"})
        assert welcome["type"] == "welcome"
        await ws.close()
    asyncio.run(run())
    assert server.stats().rejected.get("origin") == 1


# -- roles, frames ------------------------------------------------------------------------------
def test_first_client_controls_others_watch_and_control_passes_on(start_server, recorder):
    server = start_server()

    async def run():
        a, wa = await open_ws(server, name="A")
        b, wb = await open_ws(server, name="B")
        c, wc = await open_ws(server, name="C", role="watch")
        assert (wa["role"], wb["role"], wc["role"]) == ("control", "watch", "watch")
        assert wa["format"] == "raw"                         # loopback: raw unless asked
        server.submit_frame(FRAME, 1.0)
        seqs = set()
        for ws in (a, b, c):
            header, payload = await next_frame(ws)
            seqs.add(header.seq)
            assert np.array_equal(np.frombuffer(payload, np.uint8).reshape(30, 40), FRAME)
        assert len(seqs) == 1                                # everyone gets the same frame
        await b.send(P.client_message("twist", linear=0.3, angular=0.0))
        status = await next_json(b, "status")
        assert "watching" in status["text"] and not status["ok"]
        await a.send(P.client_message("twist", linear=0.4, angular=0.1))
        await a.send(P.client_message("head", rpy=[0, 0, 0.2]))
        recorder.wait(lambda r: r.twists and r.heads)
        assert recorder.twists == [(0.4, 0.1)]
        await a.close()                                      # controller leaves while moving
        role = await next_json(b, "role")
        assert role == {"type": "role", "role": "control", "controller": wb["client_id"]}
        recorder.wait(lambda r: r.twists[-1] == (0.0, 0.0))  # the avatar is stopped at once
        await b.send(P.client_message("control", want=False))
        assert (await next_json(c, "role"))["controller"] == wb["client_id"]
        assert (await next_json(c, "role")) == {"type": "role", "role": "watch", "controller": None}
        for ws in (b, c):
            await ws.close()
    asyncio.run(run())
    stats = server.stats()
    assert stats.connections == 3 and stats.refused_total == 0


def test_only_the_controlling_page_reports_what_it_composited(start_server, recorder):
    """The display rate is judged by the wearer's page: a watcher's report is dropped without a
    reply, the controller's reaches the owner, a report no page can make is refused."""
    server = start_server()

    async def run():
        a, _ = await open_ws(server, name="wearer")
        b, _ = await open_ws(server, name="watcher", role="watch")
        await b.send(P.client_message("presented", fps=30.0, refresh=90))
        await a.send(P.client_message("presented", fps=57.6, refresh=90))
        await a.send(P.client_message("presented", fps=59.0, refresh=0))
        recorder.wait(lambda r: len(r.presented) == 2)
        await a.send(P.client_message("presented", fps=-1.0))
        refused = await next_json(a, "refused")
        assert refused["code"] == "bad_field" and "fps" in refused["reason"]
        await b.send(P.client_message("ping", t=1.0))
        assert (await next_json(b))["type"] == "pong"        # nothing was said to the watcher before its pong
        for ws in (a, b):
            await ws.close()
    asyncio.run(run())
    assert recorder.presented == [(57.6, 90.0), (59.0, None)]


def test_garbage_is_refused_and_counted_while_another_client_keeps_streaming(start_server, recorder):
    server = start_server(max_refused=8)
    received: list[int] = []

    async def run():
        good, _ = await open_ws(server, name="good")
        bad, _ = await open_ws(server, name="bad", role="watch")

        async def stream():
            while True:
                header, _ = await next_frame(good)
                received.append(header.seq)

        streaming = asyncio.create_task(stream())
        feeding = asyncio.create_task(keep_submitting(server))
        try:
            garbage = ["not json", "[1,2]", '{"type":"warp"}', '{"type":"twist","linear":"x","angular":0}',
                       json.dumps({"type": "key", "key": "+", "pad": "x" * 5000}), b"\x00\x01binary"]
            codes = []
            for g in garbage:
                await bad.send(g)
                codes.append((await next_json(bad, "refused"))["code"])
            assert codes == ["not_json", "not_object", "unknown_type", "bad_field", "oversized", "binary"]
            before = len(received)
            await bad.send("junk")
            await bad.send("junk")                            # 8th refusal: dropped
            bye = await next_json(bad, "bye")
            assert "refused" in bye["reason"]
            assert await closed(bad)
            while len(received) < before + 10:               # the good client still streams
                await asyncio.sleep(0.02)
        finally:
            streaming.cancel()
            feeding.cancel()
        stats = server.stats()
        assert [c.name for c in stats.clients] == ["good"]
        assert stats.clients[0].refused == {} and stats.clients[0].role == "control"
        assert stats.dropped == {"abuse": 1} and stats.refused_total == 8
        await good.close()
    asyncio.run(run())
    assert received == sorted(received) and len(received) >= 10
    assert any("dropped" in e and "'bad'" in e for e in recorder.events)


def test_message_above_the_hard_limit_drops_the_client(start_server, wait_until):
    server = start_server()

    async def run():
        ws, _ = await open_ws(server)
        await ws.send("x" * 70000)
        assert await closed(ws)
        assert ws.close_code == 1009
    asyncio.run(run())
    wait_until(lambda: server.stats().dropped, what="the drop counted")   # the client saw the close first
    stats = server.stats()
    assert stats.dropped == {"oversized": 1} and stats.refused_total == 1


def test_flooding_client_is_refused_beyond_the_rate_limit(start_server):
    server = start_server(max_rate=5.0, max_refused=10000)

    async def run():
        ws, _ = await open_ws(server)
        for i in range(100):
            await ws.send(P.client_message("ping", t=i))
        refused = await next_json(ws, "refused")
        assert refused["code"] == "rate"
        while server.stats().clients[0].received < 100:
            await asyncio.sleep(0.01)
        refused = server.stats().clients[0].refused
        assert set(refused) == {"rate"} and refused["rate"] >= 50
        await ws.close()
    asyncio.run(run())


def test_slow_client_skips_stale_frames_instead_of_queueing(start_server, wait_until):
    server = start_server()

    async def run():
        ws, _ = await open_ws(server, window=1)              # one frame in flight, then wait for an ack
        server.submit_frame(FRAME, 0.0)
        first, _ = await next_frame(ws)
        for _ in range(10):                                  # ten frames while the client "draws"
            last = server.submit_frame(FRAME, 0.0)
        wait_until(lambda: server.stats().frames_submitted == last, what="frames submitted")
        await ws.send(P.client_message("ack", seq=first.seq))
        second, _ = await next_frame(ws)
        assert second.seq == last                            # the newest, not the next in line
        await ws.send(P.client_message("ack", seq=second.seq))
        await ws.send(P.client_message("ack", seq=second.seq + 5))   # ack of a frame never sent
        assert (await next_json(ws, "refused"))["code"] == "bad_field"
        stats = server.stats().clients[0]
        assert stats.frames_sent == 2 and stats.frames_skipped == 9 and stats.ack_rtt_ms is not None
        await ws.close()
    asyncio.run(run())


# -- input ----------------------------------------------------------------------------------------
def test_deadman_sends_one_zero_twist_when_teleop_stops(start_server, recorder):
    server = start_server(deadman_s=0.3)

    async def run():
        ws, _ = await open_ws(server)
        await ws.send(P.client_message("twist", linear=0.5, angular=0.0))
        recorder.wait(lambda r: (0.0, 0.0) in r.twists)
        await ws.send(P.client_message("ping", t=1))        # a later round trip (≥ one more dead-man period)
        await next_json(ws, "pong")
        await asyncio.sleep(0.6)
        await ws.close()
    asyncio.run(run())
    assert recorder.twists == [(0.5, 0.0), (0.0, 0.0)]      # stopped exactly once
    assert any("no teleop input" in e for e in recorder.events)


def test_keys_params_and_status_lines(start_server, recorder):
    server = start_server()

    async def run():
        ws, welcome = await open_ws(server)
        await ws.send(P.client_message("key", key="+"))
        await ws.send(P.client_message("param", name="mode", value="depth"))
        recorder.wait(lambda r: r.keys and r.params)
        assert recorder.keys == [(welcome["client_id"], "+")]
        assert recorder.params == [(welcome["client_id"], "mode", "depth")]
        server.notify("spv num_phosphenes 1000 → 1100", ok=True, client=welcome["client_id"])
        assert (await next_json(ws, "status"))["text"].startswith("spv num_phosphenes")
        await ws.send(P.client_message("ping", t=42.0))
        pong = await next_json(ws, "pong")
        assert pong["t"] == 42.0 and abs(pong["server_time"] - time.time()) < 60
        await ws.close()
    asyncio.run(run())


# -- security ------------------------------------------------------------------------------------
def test_off_loopback_binding_requires_a_generated_token(start_server):
    server = start_server(host="0.0.0.0")
    assert len(server.token) >= 16
    assert all(url.endswith(f"?token={server.token}") for url in server.urls())
    base = f"http://127.0.0.1:{server.port}/"
    with pytest.raises(urllib.error.HTTPError) as err:
        urllib.request.urlopen(base)
    assert err.value.code == 403
    err.value.close()
    assert urllib.request.urlopen(base + f"?token={server.token}").status == 200

    async def run():
        for token in ("", "wrong"):
            ws, first = await open_ws(server, token=token)
            assert first == {"type": "bye", "reason": "wrong or missing token"}
            assert await closed(ws)
        ws, welcome = await open_ws(server, token=server.token)
        assert welcome["type"] == "welcome"
        await ws.close()
        tcp = await Tcp.open(server)
        await tcp.send(P.client_message("hello"))
        assert (await tcp.next_json())["type"] == "bye"
        await tcp.close()
    asyncio.run(run())
    assert server.stats().rejected == {"token": 3}


def test_hello_rules(start_server):
    server = start_server(hello_timeout_s=0.3, max_clients=1)

    async def run():
        async with connect(f"ws://127.0.0.1:{server.port}/ws") as ws:
            await ws.send(P.client_message("ping", t=1))      # not a hello
            assert (await next_json(ws))["reason"] == "the first message must be a hello"
        async with connect(f"ws://127.0.0.1:{server.port}/ws") as ws:
            assert await closed(ws)                           # silent: no hello in time
        first, _ = await open_ws(server)
        second, bye = await open_ws(server)
        assert "full" in bye["reason"]
        await second.close()
        await first.close()
    asyncio.run(run())
    assert server.stats().rejected == {"no_hello": 1, "hello_timeout": 1, "full": 1}


def test_silent_client_is_dropped(start_server):
    server = start_server(idle_timeout_s=0.3)

    async def run():
        ws, _ = await open_ws(server)
        assert await closed(ws)
    asyncio.run(run())
    assert server.stats().dropped == {"idle": 1}


# -- TCP endpoint ---------------------------------------------------------------------------------
def test_tcp_clients_speak_the_same_protocol(start_server, recorder):
    server = start_server(compression="png")

    async def run():
        tcp = await Tcp.open(server)
        await tcp.send(P.client_message("hello", name="native", format="raw"))
        welcome = await tcp.next_json()
        assert welcome["type"] == "welcome" and welcome["format"] == "raw"   # the client's choice wins
        server.submit_frame(FRAME, 5.0)
        while True:
            kind, data = await tcp.recv()
            if kind == P.TCP_FRAME:
                break
        header, payload = P.unpack_frame(data)
        assert header.format == P.FORMAT_RAW and header.stamp == 5.0 and bytes(payload) == FRAME.tobytes()
        await tcp.send(P.client_message("head", q=[0, 0, 0, 1]))
        recorder.wait(lambda r: r.heads)
        await tcp.send("hello?", kind=9)
        assert (await tcp.next_json("refused"))["code"] == "bad_kind"
        await tcp.send("", length=1 << 20)                  # announces 1 MiB: dropped at once
        with pytest.raises(asyncio.IncompleteReadError):
            while True:
                await tcp.recv()
        # a PNG client of the same server
        png = await Tcp.open(server)
        await png.send(P.client_message("hello"))
        assert (await png.next_json())["format"] == "png"
        await png.close()
    asyncio.run(run())
    stats = server.stats()
    assert stats.dropped == {"oversized": 1}
    assert recorder.heads[0][0] == (0.0, 0.0, 0.0, 1.0)


# -- start-up and input errors ---------------------------------------------------------------------
def test_port_in_use_is_one_clear_error(start_server):
    server = start_server()
    with pytest.raises(ServerError, match=f"cannot listen on 127.0.0.1:{server.port}.*in use"):
        start_server(port=server.port)


def test_bad_frames_and_configs_are_refused(start_server):
    server = start_server()
    with pytest.raises(ValueError, match="uint8"):
        server.submit_frame(np.zeros((4, 4), np.float64), 0.0)
    with pytest.raises(ValueError, match="compression"):
        start_server(compression="zip")
    with pytest.raises(ValueError, match="tls_cert and tls_key"):
        start_server(tls_cert="cert.pem")


@pytest.mark.skipif(shutil.which("openssl") is None, reason="openssl is needed to make a test certificate")
def test_tls_serves_https_and_wss(start_server, tmp_path):
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out", str(cert),
                    "-days", "1", "-subj", "/CN=127.0.0.1"], check=True, capture_output=True)
    server = start_server(tls_cert=str(cert), tls_key=str(key))
    assert server.urls()[0].startswith("https://")
    ctx = ssl.create_default_context(cafile=str(cert))
    ctx.check_hostname = False
    with urllib.request.urlopen(f"https://127.0.0.1:{server.port}/", context=ctx) as r:
        assert r.status == 200

    async def run():
        ws, welcome = await open_ws(server, scheme="wss", ssl_context=ctx)
        assert welcome["type"] == "welcome"
        await ws.close()
    asyncio.run(run())
    with pytest.raises(ServerError, match="TLS"):
        start_server(tls_cert=str(tmp_path / "missing.pem"), tls_key=str(key))
