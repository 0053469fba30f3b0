"""Eye gaze end to end: a native-style TCP client sends a gaze trace at 120 Hz to the bridge; the
spv node (one camera frame held, a left-to-right ramp) draws the field where the eye looks. In
``locked`` the pattern moves on the display while its content stays the head camera's; in
``contingent`` the content follows the gaze; ``ignored`` puts everything back. Checked on
``/spv/frame``, on the images an image client receives and on the levels stream's offset."""
from __future__ import annotations

import asyncio
import math
import time

import numpy as np
import pytest

from raspv_common import topics
from raspv_common.conversions import stamp_to_seconds
from raspv_common.qos import GAZE_QOS, LATCHED_QOS
from geometry_msgs.msg import Vector3Stamped
from raspv_hmd import protocol as P
from raspv_hmd.levels_stream import SPRITES_MAGIC, levels_offset
from raspv_msgs.msg import PhospheneFrame, PhospheneMap
from raspv_spv.gaze import direction_from_angles, field_offset_px, shift_image

from ..spv.test_spv_node_reprojection import Source, _first_frame, head_msg
from .test_bridge_node import URL
from .test_server import Tcp

pytestmark = pytest.mark.integration

YAW_DEG = 10.0                     # the eye looks 10° left after the saccade


async def next_frame(tcp: Tcp, predicate=lambda h, p: True, timeout=20.0):
    """The next frame (header, payload) on a TCP client that ``predicate`` accepts (acks every frame)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        kind, data = await tcp.recv(timeout=deadline - time.monotonic())
        if kind == P.TCP_FRAME and data[:4] != SPRITES_MAGIC:
            header, payload = P.unpack_frame(data)
            await tcp.send(P.client_message("ack", seq=header.seq))
            if predicate(header, payload):
                return header, bytes(payload)
    raise TimeoutError("no such frame")


async def send_trace(tcp: Tcp, rate_hz: float = 120.0) -> None:
    """0.25 s straight ahead, a 40 ms saccade to YAW_DEG left, 0.5 s there (sender's clock in t)."""
    yaws = [0.0] * 30 + [YAW_DEG * (k + 1) / 5 for k in range(5)] + [YAW_DEG] * 60
    t0 = time.time()
    for k, yaw in enumerate(yaws):
        d = direction_from_angles(yaw, 0.0)
        await tcp.send(P.client_message("gaze", dir=[float(c) for c in d], t=t0 + k / rate_hz))
        await asyncio.sleep(max(0.0, t0 + (k + 1) / rate_hz - time.time()))


def start_gaze_graph(graph, probe, tcp_port: int = 0):
    """spv (gaze locked, one held ramp frame) + bridge → (graph, /spv/frame collector, the map,
    the frame's stamp, its levels, a predicate "a lit frame of that stamp")."""
    g = graph({"launch": {"nodes": [{"kind": "spv"}, {"kind": "bridge"}]},
               "spv": {"ros__parameters": {"device": "optimist", "width": 200, "mode": "grey", "temporal": False,
                                           "rate": 25.0, "stale_inputs": False, "camera_source": "sim",
                                           "gaze_mode": "locked"}},
               "bridge": {"ros__parameters": {"port": 0, "tcp_port": tcp_port}}})
    g.wait_for_output(r"open http://127\.0\.0\.1:\d+/ in a browser", timeout=60)
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    the_map = probe.wait_for_message(topics.SPV_MAP, PhospheneMap, timeout=60, qos=LATCHED_QOS)
    src = Source(probe)
    src.head.publish(head_msg(probe, 0.0))

    def of(stamp):
        return lambda f: abs(stamp_to_seconds(f.source_stamp) - stamp) < 1e-6 and max(f.levels) > 0
    t0, still = _first_frame(src, frames, of)
    return g, frames, the_map, t0, still, of(t0)


def test_a_native_client_drives_gaze_locked_and_contingent_phosphenes(graph, probe):
    gazes = probe.subscribe(topics.GAZE_DIRECTION, Vector3Stamped, qos=GAZE_QOS)
    g, frames, the_map, t0, still, of_t0 = start_gaze_graph(graph, probe)
    tcp_port = int(g.wait_for_output(URL, timeout=60).group(3))
    expected = np.round(field_offset_px(direction_from_angles(YAW_DEG, 0.0), the_map.focal_px))
    assert expected[0] < -10                            # looking left moves the field left by ~35 px

    def gazed(f, mode_levels):
        return (of_t0(f) and (round(f.field_offset_x_px), round(f.field_offset_y_px)) == tuple(expected)
                and mode_levels(np.array(f.levels)))

    async def run():
        server = type("S", (), {"tcp_port": tcp_port})
        eye = await Tcp.open(server)                    # the headset: controls, draws the levels itself
        await eye.send(P.client_message("hello", name="tracker", format="levels", window=2))
        assert (await eye.next_json("welcome"))["role"] == "control"
        view = await eye.next_json("view")
        assert view["focal_px"] == pytest.approx(the_map.focal_px, rel=1e-5)
        watcher = await Tcp.open(server)                # an image client (the /spv/image render)
        await watcher.send(P.client_message("hello", name="monitor", role="watch", format="raw", window=2))
        await watcher.next_json("welcome")
        _, before = await next_frame(watcher, lambda h, p: h.stamp > t0 and np.frombuffer(p, np.uint8).any())
        await send_trace(eye)
        t_sent = time.time()
        # locked: the field moved, its content is still the head camera's straight-ahead view
        locked = frames.wait(1, timeout=30, predicate=lambda f: stamp_to_seconds(f.header.stamp) > t_sent
                             and gazed(f, lambda lv: np.array_equal(lv, still)))[0]
        assert not locked.saccade
        h, image = await next_frame(watcher, lambda h, p: h.stamp > t_sent)
        img0 = np.frombuffer(before, np.uint8).reshape(h.height, h.width)
        img = np.frombuffer(image, np.uint8).reshape(h.height, h.width)
        assert np.array_equal(img, shift_image(img0, *expected.astype(int)))     # the same pattern, moved
        _, payload = await next_frame(eye, lambda h, p: h.format == P.FORMAT_LEVELS and h.stamp > t_sent)
        assert levels_offset(payload) == tuple(expected)       # the page draws it moved too
        # contingent: the field moved and its content follows the eye (left of a left-dark ramp: darker)
        [(_, ok, _)] = await asyncio.to_thread(probe.set_params, "spv", {"gaze_mode": "contingent"})
        assert ok
        t_set = time.time()
        contingent = frames.wait(1, timeout=30, predicate=lambda f: stamp_to_seconds(f.header.stamp) > t_set
                                 and gazed(f, lambda lv: np.mean(lv != still) > 0.3))[0]
        lv = np.array(contingent.levels, dtype=int)
        both = (lv > 0) & (still > 0)
        assert both.sum() > 50 and (lv[both] <= still[both]).all() and (lv[both] < still[both]).mean() > 0.5
        # ignored: centred, as captured
        [(_, ok, _)] = await asyncio.to_thread(probe.set_params, "spv", {"gaze_mode": "ignored"})
        assert ok
        t_set = time.time()
        frames.wait(1, timeout=30, predicate=lambda f: stamp_to_seconds(f.header.stamp) > t_set and of_t0(f)
                    and f.field_offset_x_px == 0.0 and np.array_equal(np.array(f.levels), still))
        await eye.close()
        await watcher.close()
    asyncio.run(run())
    # the bridge published every sample on the standard topic, with the sender's 120 Hz timing
    samples = gazes.wait(95, timeout=10)
    stamps = np.array([stamp_to_seconds(m.header.stamp) for m in samples])
    assert np.median(np.diff(stamps)) == pytest.approx(1 / 120, abs=1e-3) and np.all(np.diff(stamps) > 0)
    last = samples[-1].vector
    assert samples[-1].header.frame_id == "head"
    assert math.degrees(math.atan2(last.y, last.x)) == pytest.approx(YAW_DEG, abs=1e-4)
