"""Keyboard teleoperation logic: key decoding, teleop_twist_keyboard mapping, timeout, head keys."""
from __future__ import annotations

import math

import pytest

from raspv_sim.avatar import head_angles, head_quaternion
from raspv_sim.teleop_keys import HELP, KeyDecoder, TeleopConfig, TeleopKeys


def test_decoder_turns_bytes_into_keys_including_split_escape_sequences():
    d = KeyDecoder()
    assert d.feed(b"ik\x1b[A\x1b[D,") == ["i", "k", "up", "left", ","]
    assert d.feed(b"\x1b[") == []                 # the rest of the sequence comes later
    assert d.feed(b"C") == ["right"]
    assert d.feed(b"\x1b") == [] and d.flush() == ["esc"]
    assert d.feed(b"\x03") == ["ctrl-c"]


def test_motion_keys_follow_teleop_twist_keyboard():
    k = TeleopKeys(TeleopConfig(linear_speed=0.5, angular_speed=1.0, key_timeout=0.0))
    expected = {"i": (0.5, 0.0), "o": (0.5, -1.0), "j": (0.0, 1.0), "l": (0.0, -1.0), "u": (0.5, 1.0),
                ",": (-0.5, 0.0), ".": (-0.5, 1.0), "m": (-0.5, -1.0), "k": (0.0, 0.0)}
    for key, (v, w) in expected.items():
        k.handle(key, 0.0)
        assert k.velocity(100.0) == pytest.approx((v, w)), key     # timeout 0: latched
    k.handle("i", 0.0)
    k.handle("%", 0.0)                                              # any other key stops
    assert k.velocity(0.0) == (0.0, 0.0)


def test_speed_keys_scale_by_ten_percent():
    k = TeleopKeys(TeleopConfig(linear_speed=1.0, angular_speed=1.0))
    k.handle("q", 0.0)
    assert (k.linear_speed, k.angular_speed) == pytest.approx((1.1, 1.1))
    k.handle("x", 0.0)
    k.handle("e", 0.0)
    assert (k.linear_speed, k.angular_speed) == pytest.approx((0.99, 1.21))


def test_motion_stops_after_the_key_timeout():
    k = TeleopKeys(TeleopConfig(linear_speed=0.5, key_timeout=0.7))
    k.handle("i", 10.0)
    assert k.velocity(10.5) == (0.5, 0.0)
    k.handle("i", 10.6)                                             # auto-repeat keeps it going
    assert k.velocity(11.2) == (0.5, 0.0)
    assert k.velocity(11.4) == (0.0, 0.0)


def test_arrow_keys_turn_the_head_within_limits_and_h_recentres():
    k = TeleopKeys(TeleopConfig(head_step_deg=10.0, max_head_yaw_deg=30.0))
    k.handle("i", 0.0)
    for _ in range(5):
        k.handle("left", 0.1)
    k.handle("down", 0.2)
    k.handle("]", 0.3)
    roll, pitch, yaw = k.head_angles()
    assert (math.degrees(roll), math.degrees(pitch), math.degrees(yaw)) == pytest.approx((10.0, 10.0, 30.0))
    assert k.velocity(0.3) == (0.5, 0.0)                            # head keys do not stop the body
    assert head_angles(head_quaternion(roll, pitch, yaw)) == pytest.approx((roll, pitch, yaw))
    k.handle("h", 0.4)
    assert k.head_angles() == (0.0, 0.0, 0.0)


def test_ctrl_c_quits_and_help_lists_the_keys():
    k = TeleopKeys()
    k.handle("i", 0.0)
    assert k.handle("ctrl-c", 0.1) == "quit" and k.quit and k.velocity(0.1) == (0.0, 0.0)
    for text in ("u    i    o", "q/z", "arrows"):
        assert text in HELP
