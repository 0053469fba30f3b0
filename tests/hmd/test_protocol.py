"""Headset protocol: client message validation, orientation conventions, frame headers."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from raspv_hmd import protocol as P


def rotate(q, v):
    """Rotate vector v by unit quaternion q (x, y, z, w)."""
    x, y, z, w = q
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    return R @ np.asarray(v, float)


def test_valid_messages_parse_to_their_types():
    assert P.parse_client_message('{"type":"twist","linear":0.5,"angular":-1}') == P.Twist(0.5, -1.0)
    assert P.parse_client_message('{"type":"key","key":"+"}') == P.Key("+")
    assert P.parse_client_message('{"type":"param","name":"mode","value":"depth"}') == P.SetParam("mode", "depth")
    assert P.parse_client_message('{"type":"ack","seq":7}') == P.Ack(7)
    assert P.parse_client_message('{"type":"ping","t":12.5}') == P.Ping(12.5)
    assert P.parse_client_message('{"type":"control","want":false}') == P.Control(False)
    hello = P.parse_client_message('{"type":"hello","token":"abc","role":"watch","format":"png","window":2}')
    assert hello == P.Hello(token="abc", role="watch", format="png", window=2)
    assert P.parse_client_message(b'{"type":"hello"}') == P.Hello()


@pytest.mark.parametrize("text, code", [
    ("not json", "not_json"),
    ("[1, 2]", "not_object"),
    ('{"type":"teleport"}', "unknown_type"),
    ('{"linear": 1}', "unknown_type"),
    ('{"type":"twist","linear":"fast","angular":0}', "bad_field"),
    ('{"type":"twist","linear":NaN,"angular":0}', "bad_field"),
    ('{"type":"twist","linear":1e9,"angular":0}', "bad_field"),
    ('{"type":"twist","linear":true,"angular":0}', "bad_field"),
    ('{"type":"head"}', "bad_field"),
    ('{"type":"head","q":[0,0,0]}', "bad_field"),
    ('{"type":"head","q":[0,0,0,0]}', "bad_field"),
    ('{"type":"head","q":[0,0,0,1],"frame":"unreal"}', "bad_field"),
    ('{"type":"head","rpy":[0,0,100]}', "bad_field"),
    ('{"type":"head","rpy":[0,0]}', "bad_field"),
    ('{"type":"key","key":"' + "x" * 40 + '"}', "bad_field"),
    ('{"type":"key","key":5}', "bad_field"),
    ('{"type":"param","name":"mode","value":[1,2]}', "bad_field"),
    ('{"type":"param","name":"mode"}', "bad_field"),
    ('{"type":"ack","seq":-1}', "bad_field"),
    ('{"type":"control","want":"yes"}', "bad_field"),
    ('{"type":"hello","protocol":2}', "version"),
    ('{"type":"hello","role":"admin"}', "bad_field"),
    ('{"type":"hello","window":100}', "bad_field"),
])
def test_malformed_messages_are_refused_with_a_code(text, code):
    with pytest.raises(P.ProtocolError) as err:
        P.parse_client_message(text)
    assert err.value.code == code
    assert str(err.value)


def test_oversized_message_is_refused_before_parsing():
    text = json.dumps({"type": "key", "key": "+", "pad": "x" * P.MAX_CLIENT_MESSAGE})
    with pytest.raises(P.ProtocolError) as err:
        P.parse_client_message(text)
    assert err.value.code == "oversized"


def test_quaternions_are_normalised_with_positive_w():
    head = P.parse_client_message('{"type":"head","q":[0,0,-0.2,-0.9],"t":5}')
    n = math.sqrt(0.2 ** 2 + 0.9 ** 2)
    assert head.quaternion == pytest.approx((0, 0, 0.2 / n, 0.9 / n))
    assert head.client_time == 5.0


def test_rpy_follows_the_base_conventions():
    # yaw > 0 looks left: the head's x (forward) axis turns towards base +y
    q = P.parse_client_message('{"type":"head","rpy":[0,0,0.5]}').quaternion
    assert rotate(q, [1, 0, 0]) == pytest.approx([math.cos(0.5), math.sin(0.5), 0])
    # pitch > 0 looks down
    q = P.rpy_to_quaternion(0, 0.3, 0)
    assert rotate(q, [1, 0, 0])[2] < 0
    for rpy in [(0.1, -0.2, 0.3), (0, 0, -2.0), (0.5, 0.4, 1.0)]:
        assert P.quaternion_to_rpy(P.rpy_to_quaternion(*rpy)) == pytest.approx(rpy)


def test_xr_orientations_are_converted_to_base():
    assert P.xr_to_base((0, 0, 0, 1)) == (0, 0, 0, 1)                  # XR identity looks ahead
    a = math.radians(40)
    turn_left = (0, math.sin(a / 2), 0, math.cos(a / 2))               # about XR +y (up) = look left
    q = P.parse_client_message(json.dumps({"type": "head", "q": list(turn_left), "frame": "xr"})).quaternion
    assert P.quaternion_to_rpy(q) == pytest.approx((0, 0, a))
    look_down = (math.sin(-a / 2), 0, 0, math.cos(-a / 2))             # about XR −x = look down
    q = P.xr_to_base(look_down)
    assert P.quaternion_to_rpy(q) == pytest.approx((0, a, 0))


def test_unity_orientations_are_converted_to_base():
    a = math.radians(30)
    yaw_right = [0, math.sin(a / 2), 0, math.cos(a / 2)]            # Unity Euler(0, 30, 0): looks right
    q = P.parse_client_message(json.dumps({"type": "head", "q": yaw_right, "frame": "unity"})).quaternion
    assert P.quaternion_to_rpy(q) == pytest.approx((0, 0, -a))
    pitch_down = [math.sin(a / 2), 0, 0, math.cos(a / 2)]           # Unity Euler(30, 0, 0): looks down
    assert P.quaternion_to_rpy(P.unity_to_base(pitch_down)) == pytest.approx((0, a, 0))
    roll = [0, 0, math.sin(a / 2), math.cos(a / 2)]                 # Unity Euler(0, 0, 30): tilts left
    assert P.quaternion_to_rpy(P.unity_to_base(roll)) == pytest.approx((-a, 0, 0))


def test_frame_header_round_trip_and_checks():
    payload = bytes(range(12))
    h = P.FrameHeader(P.FORMAT_RAW, 1, 4, 3, 9, len(payload), 100.25, 101.5)
    data = P.pack_frame_header(h) + payload
    assert len(P.pack_frame_header(h)) == 40
    got, view = P.unpack_frame(data)
    assert got == h and bytes(view) == payload
    with pytest.raises(P.ProtocolError):
        P.unpack_frame(data[:-1])
    with pytest.raises(P.ProtocolError):
        P.unpack_frame(b"XXXX" + data[4:])
    with pytest.raises(P.ProtocolError):
        P.unpack_frame(data[:20])
