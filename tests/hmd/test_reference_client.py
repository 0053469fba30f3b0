"""The Python reference client against a real server, and `raspv hmd-client`."""
from __future__ import annotations

import asyncio
import json
import socket
import threading
import time

import cv2
import numpy as np
import pytest

from raspv_bringup.cli import main as raspv
from raspv_hmd import protocol as P
from raspv_hmd.reference_client import ClientError, ClientOptions, HeadScript, parse_endpoint, run_client
from raspv_hmd.test_pattern import PhospheneTestPattern


@pytest.fixture
def streaming(start_server):
    """A server fed 800×800 test-pattern frames at ~50 Hz until the test ends."""
    stop = threading.Event()

    def start(**config):
        server = start_server(**config)
        pattern = PhospheneTestPattern()
        frames = [pattern.frame(i / 50) for i in range(25)]

        def feed():
            i = 0
            while not stop.is_set():
                server.submit_frame(frames[i % len(frames)], time.time())
                i += 1
                stop.wait(0.02)
        threading.Thread(target=feed, daemon=True).start()
        return server

    yield start
    stop.set()


def test_endpoints_from_urls():
    assert parse_endpoint("http://127.0.0.1:8765/?token=abc") == parse_endpoint("ws://127.0.0.1:8765/ws", "abc")
    ep = parse_endpoint("https://10.0.0.2:9000/?token=t")
    assert (ep.transport, ep.secure, ep.token, ep.ws_url) == ("websocket", True, "t", "wss://10.0.0.2:9000/ws")
    assert parse_endpoint("tcp://localhost:8766").transport == "tcp"
    for bad in ("localhost:8765", "ftp://x:1", "tcp://host", "http://h:99999/"):
        with pytest.raises(ValueError):
            parse_endpoint(bad)


@pytest.mark.parametrize("transport, fmt", [("websocket", "raw"), ("tcp", "png")])
def test_client_streams_moves_the_head_and_measures(streaming, recorder, transport, fmt):
    server = streaming()
    url = f"http://127.0.0.1:{server.port}/" if transport == "websocket" else f"tcp://127.0.0.1:{server.tcp_port}"
    options = ClientOptions(format=fmt, duration_s=30, max_frames=25, head=HeadScript(yaw_deg=30, period_s=1.0),
                            keep_last_frame=True)
    report = asyncio.run(run_client(parse_endpoint(url), options))
    assert report.frames == 25 and report.role == "control" and report.formats_seen == {fmt: 25}
    assert report.size == (800, 800) and report.last_frame.shape == (800, 800) and report.last_frame.max() > 200
    assert report.rtt_ms and report.clock_offset_s is not None and abs(report.clock_offset_s) < 0.05
    # latencies go through the clock offset estimated from the fastest ping, whose error is at
    # most half that ping's round trip (asymmetric delays on a loaded machine): never lower
    assert len(report.latency_ms) == 25 and min(report.latency_ms) > -(min(report.rtt_ms) / 2 + 1.0)
    assert report.heads_sent
    recorder.wait(lambda r: len(r.heads) >= len(report.heads_sent))
    sent = [q for _, q in report.heads_sent]
    got = [q for q, _, _ in recorder.heads]
    assert np.allclose(got, sent)                                  # every head message, in order
    yaws = [P.quaternion_to_rpy(q)[2] for q in got]
    assert max(np.abs(yaws)) <= np.radians(30) + 1e-9


def test_watcher_receives_frames_but_sends_no_head(streaming, recorder):
    server = streaming()
    report = asyncio.run(run_client(parse_endpoint(f"ws://127.0.0.1:{server.port}/ws"),
                                    ClientOptions(role="watch", max_frames=5, duration_s=30)))
    assert report.frames == 5 and report.role == "watch" and not report.heads_sent and not recorder.heads


def test_client_errors_are_clear(start_server):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        free_port = s.getsockname()[1]
    with pytest.raises(ClientError, match="is the bridge running"):
        asyncio.run(run_client(parse_endpoint(f"http://127.0.0.1:{free_port}/")))
    server = start_server(token="secret")
    with pytest.raises(ClientError, match="token"):
        asyncio.run(run_client(parse_endpoint(f"http://127.0.0.1:{server.port}/")))


def test_hmd_client_command(streaming, tmp_path, capsys):
    server = streaming()
    out = tmp_path / "last.png"
    code = raspv(["hmd-client", f"http://127.0.0.1:{server.port}/", "--frames", "10", "--save-frame", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "10 frames 800x800" in text and "image time → received: p50" in text and "round trip" in text
    assert cv2.imread(str(out), cv2.IMREAD_UNCHANGED).shape == (800, 800)
    assert raspv(["hmd-client", f"tcp://127.0.0.1:{server.tcp_port}", "--frames", "3", "--json", "--watch"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["frames"] == 3 and report["transport"] == "tcp" and report["role"] == "watch"


def test_hmd_client_command_errors(capsys):
    assert raspv(["hmd-client", "localhost"]) == 2
    assert "give the URL the bridge printed" in capsys.readouterr().err
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert raspv(["hmd-client", f"http://127.0.0.1:{port}/", "--duration", "1"]) == 1
    err = capsys.readouterr().err
    assert "cannot connect" in err and "Traceback" not in err
