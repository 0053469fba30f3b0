"""Eye gaze from headset clients: the gaze message (combined or per eye, head/xr/unity frames,
validity), the sender's timing mapped onto ours, the levels stream's field offset and the display
geometry sent to clients (raspv_hmd/protocol.py, sender_clock.py, levels_stream.py, server.py)."""
from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest

from raspv_hmd import protocol as P
from raspv_hmd.levels_stream import FRAME_OFFSET, levels_offset, pack_levels_payload, unpack_levels_payload
from raspv_hmd.sender_clock import SenderClock

from .test_server import Tcp


def gaze(**fields):
    return P.parse_client_message(P.client_message("gaze", **fields))


def test_gaze_messages_combined_per_eye_and_frames():
    g = gaze(dir=[2, 0, 0], t=12.5)
    assert g == P.Gaze((1.0, 0.0, 0.0), 12.5)
    # xr: x right, y up, −z forward → head (x forward, y left, z up); unity: z forward
    assert gaze(dir=[0, 0, -1], frame="xr").direction == pytest.approx((1, 0, 0))
    assert gaze(dir=[-0.1, 0.2, -1], frame="xr").direction == pytest.approx(np.array([1, 0.1, 0.2]) / math.sqrt(1.05))
    assert gaze(dir=[0.1, 0, 1], frame="unity").direction == pytest.approx(np.array([1, -0.1, 0]) / math.sqrt(1.01))
    # per eye: the normalised mean of the valid eyes, or the one valid eye
    both = gaze(left=[1, 0.1, 0], right=[1, -0.1, 0]).direction
    assert both == pytest.approx((1.0, 0.0, 0.0))
    one = gaze(left=[1, 0.1, 0], right=[1, -0.1, 0], right_valid=False).direction
    assert one == pytest.approx(np.array([1, 0.1, 0]) / math.sqrt(1.01))
    assert gaze(left=None, right=None).direction is None
    assert gaze(valid=False).direction is None and gaze(dir=[1, 0, 0], valid=False).direction is None


@pytest.mark.parametrize("fields, says", [
    ({}, "needs 'dir'"), ({"dir": [0, 0, 0]}, "zero length"), ({"dir": [1, 0]}, "direction"),
    ({"dir": [1, "a", 0]}, "direction"), ({"dir": [-1, 0, 0]}, "80 deg"), ({"dir": [1, 0, 0], "frame": "eye"}, "frame"),
    ({"dir": [1, 0, 0], "valid": "yes"}, "valid"), ({"dir": [1, 0, 0], "t": float("inf")}, "'t'")])
def test_bad_gaze_is_refused_with_one_line(fields, says):
    with pytest.raises(P.ProtocolError, match=says) as exc:
        P.parse_client_message(P.client_message("gaze", **fields) if "inf" not in str(fields)
                               else '{"type": "gaze", "dir": [1, 0, 0], "t": 1e999}')
    assert exc.value.code == "bad_field" and "\n" not in str(exc.value)


def test_sender_clock_keeps_the_senders_intervals():
    rng = np.random.default_rng(0)
    clock = SenderClock()
    sent = 1000.0 + np.arange(240) / 120.0                      # a 120 Hz tracker on its own clock
    arrival = sent - 1000.0 + 5e8 + 0.002 + rng.exponential(0.004, sent.size)   # offset, 2 ms + jitter
    mapped = np.array([clock.map(s, a) for s, a in zip(sent, arrival)])
    assert np.all(mapped <= arrival + 1e-12)
    # after the first second the envelope has found the fastest delivery: intervals are the sender's
    steady = mapped[120:]
    assert np.allclose(np.diff(steady), 1 / 120.0, atol=1e-4)
    late = steady - (sent[120:] - 1000.0 + 5e8)                 # behind the true time on our clock
    assert np.all((late >= 0.002 - 1e-9) & (late < 0.0025))     # by the shortest delay only
    # jitter would have been: arrival intervals vary by milliseconds
    assert np.ptp(np.diff(arrival)) > 0.005


def test_levels_payload_carries_the_field_offset_only_when_there_is_one():
    w = np.linspace(0, 1, 10, dtype=np.float32)
    plain = pack_levels_payload(3, w, None, 1, 0)
    assert levels_offset(plain) == (0, 0) and not unpack_levels_payload(plain)[3] & FRAME_OFFSET
    moved = pack_levels_payload(3, w, None, 1, 0, (-37, 12))
    assert len(moved) == len(plain) + 4 and levels_offset(moved) == (-37, 12)
    map_id, weights, lv, flags = unpack_levels_payload(moved)
    assert map_id == 3 and flags & FRAME_OFFSET and np.allclose(weights, w, atol=1e-4) and lv is None
    levelled = pack_levels_payload(3, w, np.arange(10), 4, 1, (5, -6))
    assert levels_offset(levelled) == (5, -6) and np.array_equal(unpack_levels_payload(levelled)[2], np.arange(10))
    with pytest.raises(P.ProtocolError):
        unpack_levels_payload(moved[:-1])


def test_server_hands_gaze_to_its_owner_and_tells_clients_the_display(start_server, recorder):
    server = start_server()
    server.show_view(width=400, height=300, focal_px=500.0, spacing_px=12.5, fov_deg=43.6)

    async def run():
        tcp = await Tcp.open(server)
        await tcp.send(P.client_message("hello", name="tracker"))
        welcome = await tcp.next_json()
        view = await tcp.next_json("view")
        assert view["focal_px"] == 500.0 and view["width"] == 400
        await tcp.send(P.client_message("gaze", dir=[1, 0.1, 0], t=77.0))
        await tcp.send(P.client_message("gaze", valid=False, t=77.01))
        recorder.wait(lambda r: len(r.gazes) == 2)
        (cid, d, t, _), (_, none, t2, _) = recorder.gazes
        assert cid == welcome["client_id"] and d == pytest.approx(np.array([1, 0.1, 0]) / math.sqrt(1.01))
        assert t == 77.0 and none is None and t2 == 77.01
        await tcp.send(P.client_message("gaze", dir=[1, 0, 0]))
        recorder.wait(lambda r: len(r.gazes) == 3)
        assert recorder.gazes[2][2] is None
        await tcp.close()
    asyncio.run(run())
