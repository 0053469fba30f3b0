"""The headset protocol (version 1): message formats shared by the WebSocket and TCP endpoints.

Everything a client sends is a JSON object (a WebSocket text message, or a TCP message of kind
``JSON``); the server sends JSON objects too, and phosphene frames as binary messages that
start with :data:`FRAME_HEADER`. docs/hmd.md is the reference for native clients; this module
is its executable form (parsing and validation, no I/O, no rclpy).

Frames and units: head orientations are unit quaternions (x, y, z, w) of the head relative to the
avatar's base (x forward, y left, z up; identity looks straight ahead), or roll/pitch/yaw in
radians (pitch > 0 looks down, yaw > 0 looks left). ``"frame": "xr"`` marks a quaternion in the
OpenXR/WebXR convention (x right, y up, −z forward) and ``"frame": "unity"`` one in Unity's
left-handed convention (x right, y up, z forward); both are converted here. Twists are m/s and
rad/s.
"""
from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from typing import Any

PROTOCOL_VERSION = 1

# Frame message: little-endian header, then the payload (raw pixels row-major, or a PNG file).
#   magic "RSPV", version u8, format u8, channels u8, flags u8, width u32, height u32,
#   seq u32, payload length u32, stamp f64 (image time, s), sent f64 (server wall clock, s)
FRAME_MAGIC = b"RSPV"
FRAME_HEADER = struct.Struct("<4sBBBBIIIIdd")
FORMAT_RAW = 0
FORMAT_PNG = 1
FORMAT_LEVELS = 2                  # per-phosphene weights drawn by the client (raspv_hmd/levels_stream.py)
FORMAT_NAMES = {FORMAT_RAW: "raw", FORMAT_PNG: "png", FORMAT_LEVELS: "levels"}
FLAG_GREEN = 1                     # a 1-channel frame that is the green channel of an rgb8 image

# TCP framing: payload length u32, kind u8, then the payload.
TCP_HEADER = struct.Struct("<IB")
TCP_JSON = 1
TCP_FRAME = 2

MAX_CLIENT_MESSAGE = 4096          # bytes; larger client messages are refused (counted)
MAX_KEY_LENGTH = 16                # characters of a key name
MAX_NAME_LENGTH = 64               # client name and parameter names
MAX_HEAD_RPY = 2 * math.pi         # rad; larger angles are refused as nonsense


class ProtocolError(ValueError):
    """A message the server refuses; ``code`` names the rule it broke (counted per client)."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


# -- client → server ------------------------------------------------------------------------

@dataclass(frozen=True)
class Hello:
    token: str = ""
    name: str = ""
    role: str = "control"          # "control" (wants control) or "watch"
    format: str = "auto"           # "auto", "raw", "png" or "levels" (the client draws the sprites)
    window: int = 0                # frames in flight before an ack is needed (0: no acks)


@dataclass(frozen=True)
class Head:
    quaternion: tuple[float, float, float, float]    # (x, y, z, w), head relative to base
    client_time: float | None = None                 # sender's wall clock [s], for latency


@dataclass(frozen=True)
class Gaze:
    """Eye gaze: a unit direction in the head frame (x forward, y left, z up), or None when the
    tracker has no valid sample (blink, lost eye); ``client_time`` the sender's clock [s]."""

    direction: tuple[float, float, float] | None
    client_time: float | None = None


@dataclass(frozen=True)
class Twist:
    linear: float                  # m/s forward
    angular: float                 # rad/s, positive turns left


@dataclass(frozen=True)
class Key:
    key: str


@dataclass(frozen=True)
class SetParam:
    name: str
    value: Any


@dataclass(frozen=True)
class Ack:
    seq: int


@dataclass(frozen=True)
class Ping:
    t: float


@dataclass(frozen=True)
class Presented:
    """What the controlling page composited over its last second: frames/s, and the refresh clock
    it presents on [Hz] (None: the browser's frame callback). The spv node judges the display
    rate by it (raspv_spv/page_presentation.py)."""

    fps: float
    refresh_hz: float | None = None


@dataclass(frozen=True)
class Control:
    want: bool


@dataclass(frozen=True)
class Experiment:
    """The subject's answer to experiment instructions: "start" the trial or "abort" it."""

    action: str
    id: str = ""                   # the instructions' id it answers


EXPERIMENT_ACTIONS = ("start", "abort")
ClientMessage = Hello | Head | Gaze | Twist | Key | SetParam | Ack | Ping | Presented | Control | Experiment
CONTROL_MESSAGES = (Head, Gaze, Twist, Key, SetParam, Experiment, Presented)   # only the controlling client may send these


def _number(obj: dict, field: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    v = obj.get(field)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
        raise ProtocolError("bad_field", f"'{field}' must be a finite number in [{lo}, {hi}], got {v!r}")
    return float(v)


def _string(obj: dict, field: str, default: str | None = None, max_length: int = MAX_NAME_LENGTH,
            choices: tuple[str, ...] | None = None) -> str:
    v = obj.get(field, default)
    if not isinstance(v, str) or len(v) > max_length or (choices is not None and v not in choices):
        allowed = f"one of {', '.join(choices)}" if choices else f"a string of at most {max_length} characters"
        raise ProtocolError("bad_field", f"'{field}' must be {allowed}, got {v!r}")
    return v


def normalise_quaternion(q: Any) -> tuple[float, float, float, float]:
    """A list of 4 finite numbers (x, y, z, w) → unit quaternion with w ≥ 0."""
    if not isinstance(q, (list, tuple)) or len(q) != 4 or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in q):
        raise ProtocolError("bad_field", f"'q' must be 4 finite numbers [x, y, z, w], got {q!r}")
    n = math.sqrt(sum(float(v) * float(v) for v in q))
    if not 0.5 < n < 2.0:
        raise ProtocolError("bad_field", f"'q' must be a unit quaternion, its norm is {n:.3g}")
    x, y, z, w = (float(v) / n for v in q)
    return (-x, -y, -z, -w) if w < 0 else (x, y, z, w)


def xr_to_base(q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """Orientation in the OpenXR/WebXR convention (x right, y up, −z forward) → base convention
    (x forward, y left, z up). The axis change is the proper rotation x_b = −z, y_b = −x, z_b = y."""
    x, y, z, w = q
    return (-z, -x, y, w)


def unity_to_base(q: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """Orientation in Unity's left-handed convention (x right, y up, z forward) → base convention.
    The axis change x_b = z, y_b = −x, z_b = y flips handedness, which negates the vector part."""
    x, y, z, w = q
    return (-z, x, -y, w)


def rpy_to_quaternion(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """Roll about x, pitch about y (positive looks down), yaw about z (positive looks left),
    applied yaw·pitch·roll; radians → (x, y, z, w)."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def quaternion_to_rpy(q: tuple[float, float, float, float]) -> tuple[float, float, float]:
    """Inverse of :func:`rpy_to_quaternion`; radians."""
    x, y, z, w = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


GAZE_FRAMES = ("head", "xr", "unity")


def gaze_to_head(v: tuple[float, float, float], frame: str) -> tuple[float, float, float]:
    """A gaze direction in ``frame`` → the head frame (x forward, y left, z up). ``xr``: OpenXR /
    WebXR eye space (x right, y up, −z forward); ``unity``: x right, y up, z forward (left-handed)."""
    x, y, z = v
    if frame == "xr":
        return (-z, -x, y)
    if frame == "unity":
        return (z, -x, y)
    return (x, y, z)


def _gaze_vector(obj: dict, field: str) -> tuple[float, float, float] | None:
    """A gaze direction field: 3 finite numbers not all zero, or null (no valid sample)."""
    v = obj.get(field)
    if v is None:
        return None
    if not isinstance(v, (list, tuple)) or len(v) != 3 or any(
            isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c) for c in v):
        raise ProtocolError("bad_field", f"'{field}' must be a direction [x, y, z] (or null), got {v!r}")
    n = math.sqrt(sum(float(c) * float(c) for c in v))
    if n < 1e-6:
        raise ProtocolError("bad_field", f"'{field}' has zero length; send \"valid\": false for a missing sample")
    return tuple(float(c) / n for c in v)


def parse_gaze(obj: dict) -> Gaze:
    """A ``gaze`` message: ``dir`` (combined, cyclopean) or ``left`` / ``right`` (each eye; the
    combined gaze is their normalised mean, or the one valid eye), ``frame``, ``valid``
    (default true; false: no usable sample), ``t``; per eye ``left_valid`` / ``right_valid``."""
    t = _number(obj, "t") if "t" in obj else None
    frame = _string(obj, "frame", "head", choices=GAZE_FRAMES)
    valid = obj.get("valid", True)
    if not isinstance(valid, bool):
        raise ProtocolError("bad_field", f"'valid' must be true or false, got {valid!r}")
    if "dir" in obj:
        d = _gaze_vector(obj, "dir")
    elif "left" in obj or "right" in obj:
        eyes = []
        for eye in ("left", "right"):
            v = _gaze_vector(obj, eye)
            ok = obj.get(f"{eye}_valid", True)
            if not isinstance(ok, bool):
                raise ProtocolError("bad_field", f"'{eye}_valid' must be true or false, got {ok!r}")
            if v is not None and ok:
                eyes.append(v)
        d = None
        if eyes:
            s = [sum(e[i] for e in eyes) for i in range(3)]
            n = math.sqrt(sum(c * c for c in s))
            d = tuple(c / n for c in s) if n > 1e-6 else None
    elif valid:
        raise ProtocolError("bad_field", "a gaze message needs 'dir' [x, y, z] or 'left'/'right', or valid: false")
    else:
        d = None
    if not valid or d is None:
        return Gaze(None, t)
    d = gaze_to_head(d, frame)
    if d[0] <= 0.17:        # more than ~80 deg from straight ahead: not an eye's gaze
        raise ProtocolError("bad_field", f"gaze {[round(c, 3) for c in d]} (head frame: x forward) points more than "
                                         "80 deg from straight ahead")
    return Gaze(d, t)


def parse_client_message(data: str | bytes) -> ClientMessage:
    """Decode and validate one client message, or raise :class:`ProtocolError`."""
    if len(data) > MAX_CLIENT_MESSAGE:
        raise ProtocolError("oversized", f"message of {len(data)} bytes; the limit is {MAX_CLIENT_MESSAGE}")
    try:
        obj = json.loads(data)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ProtocolError("not_json", f"not a JSON text: {exc}") from None
    if not isinstance(obj, dict):
        raise ProtocolError("not_object", f"expected a JSON object, got {type(obj).__name__}")
    kind = obj.get("type")
    if kind == "head":
        t = _number(obj, "t") if "t" in obj else None
        if "q" in obj:
            q = normalise_quaternion(obj["q"])
            frame = _string(obj, "frame", "base", choices=("base", "xr", "unity"))
            if frame != "base":
                q = normalise_quaternion(list(xr_to_base(q) if frame == "xr" else unity_to_base(q)))
            return Head(q, t)
        if "rpy" in obj:
            rpy = obj["rpy"]
            if not isinstance(rpy, (list, tuple)) or len(rpy) != 3:
                raise ProtocolError("bad_field", f"'rpy' must be [roll, pitch, yaw] in radians, got {rpy!r}")
            r, p, y = (_number({"rpy": v}, "rpy", -MAX_HEAD_RPY, MAX_HEAD_RPY) for v in rpy)
            return Head(rpy_to_quaternion(r, p, y), t)
        raise ProtocolError("bad_field", "a head message needs 'q' [x, y, z, w] or 'rpy' [roll, pitch, yaw]")
    if kind == "gaze":
        return parse_gaze(obj)
    if kind == "twist":
        return Twist(_number(obj, "linear", -100.0, 100.0), _number(obj, "angular", -100.0, 100.0))
    if kind == "key":
        key = _string(obj, "key", max_length=MAX_KEY_LENGTH)
        if not key:
            raise ProtocolError("bad_field", f"'key' must name a key, e.g. \"1\" or \"t\"; got {key!r}")
        return Key(key)
    if kind == "param":
        name = _string(obj, "name")
        value = obj.get("value")
        if isinstance(value, float) and not math.isfinite(value):
            raise ProtocolError("bad_field", f"'value' must be finite, got {value!r}")
        if not isinstance(value, (bool, int, float, str)):
            raise ProtocolError("bad_field", f"'value' must be a number, boolean or string, got {value!r}")
        return SetParam(name, value)
    if kind == "ack":
        return Ack(int(_number(obj, "seq", 0, 2**32 - 1)))
    if kind == "ping":
        return Ping(_number(obj, "t"))
    if kind == "presented":
        refresh = obj.get("refresh")
        return Presented(_number(obj, "fps", 0.0, 1000.0),
                         None if refresh in (None, 0) else _number(obj, "refresh", 1.0, 1000.0))
    if kind == "control":
        want = obj.get("want")
        if not isinstance(want, bool):
            raise ProtocolError("bad_field", f"'want' must be true or false, got {want!r}")
        return Control(want)
    if kind == "experiment":
        return Experiment(_string(obj, "action", choices=EXPERIMENT_ACTIONS), _string(obj, "id", ""))
    if kind == "hello":
        version = obj.get("protocol", PROTOCOL_VERSION)
        if version != PROTOCOL_VERSION:
            raise ProtocolError("version", f"protocol {version!r} is not supported; this server speaks {PROTOCOL_VERSION}")
        return Hello(token=_string(obj, "token", "", max_length=256), name=_string(obj, "name", ""),
                     role=_string(obj, "role", "control", choices=("control", "watch")),
                     format=_string(obj, "format", "auto", choices=("auto", "raw", "png", "levels")),
                     window=int(_number({"window": obj.get("window", 0)}, "window", 0, 16)))
    raise ProtocolError("unknown_type", f"unknown message type {kind!r}")


def client_message(kind: str, **fields: Any) -> str:
    """A client → server JSON message (used by the reference client and tests)."""
    return json.dumps({"type": kind, **fields}, separators=(",", ":"))


# -- server → client ------------------------------------------------------------------------

def server_message(kind: str, **fields: Any) -> str:
    """A server → client JSON message."""
    return json.dumps({"type": kind, **fields}, separators=(",", ":"))


@dataclass(frozen=True)
class FrameHeader:
    format: int          # FORMAT_RAW, FORMAT_PNG or FORMAT_LEVELS
    channels: int        # 1 (mono8) or 3 (rgb8)
    width: int
    height: int
    seq: int
    payload_length: int
    stamp: float         # time of the image (its ROS header), s
    sent: float          # server wall clock when sent, s
    flags: int = 0       # FLAG_GREEN: show the single channel as green


def pack_frame_header(h: FrameHeader) -> bytes:
    return FRAME_HEADER.pack(FRAME_MAGIC, PROTOCOL_VERSION, h.format, h.channels, h.flags, h.width, h.height,
                             h.seq, h.payload_length, h.stamp, h.sent)


def unpack_frame(data: bytes | memoryview) -> tuple[FrameHeader, memoryview]:
    """A frame message → (header, payload view); raises ProtocolError when inconsistent."""
    if len(data) < FRAME_HEADER.size:
        raise ProtocolError("bad_frame", f"frame of {len(data)} bytes is shorter than its header")
    magic, version, fmt, channels, flags, w, h, seq, n, stamp, sent = FRAME_HEADER.unpack_from(data)
    if magic != FRAME_MAGIC or version != PROTOCOL_VERSION:
        raise ProtocolError("bad_frame", f"not a protocol-{PROTOCOL_VERSION} frame (magic {magic!r}, version {version})")
    if fmt not in FORMAT_NAMES or channels not in (1, 3) or len(data) != FRAME_HEADER.size + n:
        raise ProtocolError("bad_frame", f"inconsistent frame: format {fmt}, {channels} channels, "
                                         f"{len(data) - FRAME_HEADER.size} payload bytes for {n} announced")
    if fmt == FORMAT_RAW and n != w * h * channels:
        raise ProtocolError("bad_frame", f"raw {w}x{h}x{channels} frame with {n} bytes")
    return FrameHeader(fmt, channels, w, h, seq, n, stamp, sent, flags), memoryview(data)[FRAME_HEADER.size:]
