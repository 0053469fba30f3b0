"""Viewer keys → spv parameter changes, the control rule and dead-man, frame encodings."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from raspv_hmd import protocol as P
from raspv_hmd.control import ControlArbiter, DeadMan
from raspv_hmd.frame_encoding import OutgoingFrame
from raspv_hmd.keymap import key_change, parameters_needed
from raspv_hmd.test_pattern import PhospheneTestPattern

DEVICE = {"num_phosphenes": 1000, "fov_deg": 20.0, "phosphene_fov_deg": 0.5, "num_levels": 8,
          "grid": "hexagonal", "field": "rectangular", "dropout": 0.0, "noise_px": 0.0}
MODES = ["grey", "depth", "edges"]


@pytest.mark.parametrize("key, current, expected", [
    ("+", {"num_phosphenes": 1000}, ("num_phosphenes", 1100)),
    ("-", {"num_phosphenes": 1000}, ("num_phosphenes", 900)),
    ("-", {"num_phosphenes": 3}, ("num_phosphenes", 2)),        # small counts still move
    ("+", {"num_phosphenes": 0}, ("num_phosphenes", 1100)),     # 0 = the device's 1000
    ("*", {"phosphene_fov_deg": 0.5}, ("phosphene_fov_deg", 0.55)),
    ("/", {"phosphene_fov_deg": 0.0}, ("phosphene_fov_deg", 0.45)),
    ("v", {"fov_deg": 20.0}, ("fov_deg", 19.0)),
    ("V", {"fov_deg": 0.0}, ("fov_deg", 21.0)),
    ("n", {"noise_px": 0.0}, ("noise_px", 0.0)),                # never negative
    ("N", {"noise_px": -1.0}, ("noise_px", 1.0)),
    ("o", {"dropout": 0.3}, ("dropout", 0.25)),
    ("O", {"dropout": 1.0}, ("dropout", 1.0)),
    ("l", {"num_levels": 2}, ("num_levels", 2)),
    ("L", {"num_levels": 0}, ("num_levels", 9)),
    (".", {"grid": ""}, ("grid", "rectangular")),              # device hexagonal → rectangular
    (".", {"grid": "rectangular"}, ("grid", "hexagonal")),
    (",", {"field": "circular"}, ("field", "rectangular")),
    ("j", {"mode": "depth", "max_depth": 3.0, "chess_tile": None}, ("max_depth", 2.5)),
    ("J", {"mode": "chess_floor", "max_depth": 3.0, "chess_tile": 0.5}, ("chess_tile", 0.75)),
    ("2", {}, ("mode", "depth")),
])
def test_viewer_keys(key, current, expected):
    needed = parameters_needed(key)
    assert set(current) <= set(needed) | {"device"}
    change = key_change(key, {**current, "device": "default"}, MODES, DEVICE)
    assert (change.name, change.value) == expected
    assert change.name in change.text


def test_keys_that_cannot_apply_say_why():
    with pytest.raises(KeyError):
        parameters_needed("q")
    with pytest.raises(ValueError, match="only 3 modes"):
        key_change("7", {}, MODES)
    with pytest.raises(ValueError, match="no parameter 'chess_tile'"):
        key_change("j", {"mode": "chess_floor", "chess_tile": None, "max_depth": 3.0}, MODES)
    with pytest.raises(ValueError, match="device"):
        key_change("+", {"num_phosphenes": 0}, MODES, None)


def test_controller_is_the_earliest_client_that_wants_control():
    a = ControlArbiter()
    assert a.add(1, wants=False) is False and a.controller is None
    assert a.add(2, wants=True) is True and a.controller == 2
    assert a.add(3, wants=True) is False and a.controller == 2
    assert a.set_want(1, True) is True and a.controller == 1      # earlier client asks: it takes over
    assert a.remove(1) is True and a.controller == 2
    assert a.set_want(2, False) is True and a.controller == 3
    assert a.remove(2) is False and a.remove(3) is True and a.controller is None


def test_deadman_stops_once_after_the_timeout():
    d = DeadMan(0.5)
    assert d.deadline() is None and not d.poll(10.0)
    d.input(0.4, 0.0, now=1.0)
    assert d.deadline() == pytest.approx(1.5)
    assert not d.poll(1.3)
    d.input(0.4, 0.1, now=1.3)                 # fresh input postpones the stop
    assert not d.poll(1.7)
    assert d.poll(1.8) and not d.poll(2.5)     # exactly once
    d.input(0.0, 0.0, now=3.0)                 # an explicit stop needs no dead-man
    assert d.deadline() is None and not d.poll(9.0)
    d.input(1.0, 0.0, now=10.0)
    assert d.release() and not d.release()
    with pytest.raises(ValueError):
        DeadMan(0.0)


def test_png_is_used_when_it_pays_and_decodes_exactly():
    image = PhospheneTestPattern(400, 400, count=300).frame(0.3)
    frame = OutgoingFrame(5, image, stamp=12.0)
    fmt, png = frame.payload(P.FORMAT_PNG)
    assert fmt == P.FORMAT_PNG and len(png) < 0.3 * image.size
    assert np.array_equal(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED), image)
    fmt, message = frame.message(P.FORMAT_PNG, sent=13.0)
    header, payload = P.unpack_frame(message)
    assert (header.format, header.seq, header.width, header.height, header.stamp, header.sent) == \
        (P.FORMAT_PNG, 5, 400, 400, 12.0, 13.0)
    assert frame.payload(P.FORMAT_PNG)[1] is png                 # encoded once, shared


def test_noise_goes_raw_even_when_png_is_asked_for():
    noise = np.random.default_rng(0).integers(0, 256, (120, 160, 3), dtype=np.uint8)
    frame = OutgoingFrame(1, noise, stamp=0.0)
    fmt, payload = frame.payload(P.FORMAT_PNG)
    assert fmt == P.FORMAT_RAW and payload == noise.tobytes()
    header, view = P.unpack_frame(frame.message(P.FORMAT_PNG, 0.0)[1])
    assert header.channels == 3 and np.array_equal(np.frombuffer(view, np.uint8).reshape(120, 160, 3), noise)


def test_rgb_png_keeps_channel_order():
    rgb = np.zeros((64, 64, 3), np.uint8)
    rgb[20:40, 20:40, 1] = 200
    rgb[5:10, 5:10, 0] = 90
    fmt, png = OutgoingFrame(1, rgb, 0.0).payload(P.FORMAT_PNG)
    assert fmt == P.FORMAT_PNG
    decoded = cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    assert np.array_equal(decoded, rgb)


@pytest.mark.parametrize("bad", [np.zeros((4, 4), np.float32), np.zeros((4, 4, 4), np.uint8),
                                 np.zeros((0, 4), np.uint8), [[1, 2]]])
def test_bad_frames_are_refused_with_a_message(bad):
    with pytest.raises(ValueError, match="phosphene frame"):
        OutgoingFrame(1, bad, 0.0)


def test_green_only_rgb_travels_as_one_channel():
    from raspv_hmd.reference_client import decode_payload

    green = np.zeros((50, 60, 3), np.uint8)
    green[10:30, 5:25, 1] = 180
    for wanted in (P.FORMAT_RAW, P.FORMAT_PNG):
        fmt, message = OutgoingFrame(1, green, 0.0).message(wanted, 0.0)
        header, payload = P.unpack_frame(message)
        assert header.channels == 1 and header.flags == P.FLAG_GREEN and header.format == wanted
        assert np.array_equal(decode_payload(header, payload), green)
    white = green.copy()
    white[0, 0] = 255
    header, _ = P.unpack_frame(OutgoingFrame(1, white, 0.0).message(P.FORMAT_RAW, 0.0)[1])
    assert header.channels == 3 and header.flags == 0
