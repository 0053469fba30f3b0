"""Spatial audio cues for the headset client (no rclpy): where the sounds come from.

The navigation assistant's guidance (:class:`~raspv_nav.guidance.Guidance`, world frame W) and
the newest staircase detection (camera frame C) become positions relative to the *listener*,
sent to the headset client as a ``cues`` message (docs/hmd.md) that places WebAudio panners:

- ``waypoint``: the next waypoint on the path (a beacon to walk towards);
- ``obstacle``: the nearest obstacle ahead and its distance (beeps quicken as it comes closer);
- ``stairs``: the first step of a staircase within ``stairs_range`` m, ``up`` or ``down`` (its
  own rising or falling arpeggio).

Listener frames (x forward, y left, z up, metres — the protocol's base convention):

- ``base``: the avatar's body (``/odom``). The client turns the listener by its own head
  orientation, so turning the head moves the sounds at once, without a round trip;
- ``head``: the camera itself (real cameras, replays: no body pose); the client keeps the
  listener fixed, the cues follow the camera pose.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

CUES = ("waypoint", "obstacle", "stairs")

# camera optical (x right, y down, z forward) → head (x forward, y left, z up)
HEAD_FROM_CAMERA = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class CueSettings:
    enabled: tuple[str, ...] = CUES       # cues sent at all (the client can mute each too)
    stairs_range: float = 4.0             # [m] staircases farther than this make no sound
    proximity_range: float = 1.5          # [m] reported to the client to scale the obstacle beeps
    floor_height: float = 0.0             # world z of waypoints and obstacles [m]


def listener_from_world(world_from_listener: np.ndarray, frame: str) -> np.ndarray:
    """4×4 listener ← W for a listener pose W ← base (``frame`` "base") or W ← camera optical
    (``frame`` "head"); the listener axes are x forward, y left, z up."""
    T = np.asarray(world_from_listener, dtype=float)
    inv = np.linalg.inv(T)
    if frame == "base":
        return inv
    if frame != "head":
        raise ValueError(f"listener frame must be 'base' or 'head', got {frame!r}")
    out = np.eye(4)
    out[:3, :3] = HEAD_FROM_CAMERA @ inv[:3, :3]
    out[:3, 3] = HEAD_FROM_CAMERA @ inv[:3, 3]
    return out


def _point(T: np.ndarray, p) -> list[float] | None:
    """``p`` in the listener frame, rounded to mm; None when not finite (JSON has no NaN)."""
    q = T[:3, :3] @ np.asarray(p, dtype=float) + T[:3, 3]
    return [round(float(v), 3) for v in q] if np.all(np.isfinite(q)) else None


def cues_message(guidance: Any | None, world_from_listener: np.ndarray | None, frame: str,
                 stairs: Any | None = None, listener_from_camera: np.ndarray | None = None,
                 settings: CueSettings | None = None) -> dict[str, Any] | None:
    """The ``cues`` message fields (JSON-ready), or None without a listener pose.

    ``guidance``: a Guidance (W) or None; ``world_from_listener``: W ← listener at the guidance
    stamp (base or camera optical, see ``frame``); ``stairs``: a
    :class:`~raspv_perception.stair_model.Staircase` (C) or None; ``listener_from_camera``:
    4×4 listener ← C at the stairs' stamp (None: identity up to the axis change of ``head``)."""
    s = settings or CueSettings()
    if world_from_listener is None or not np.all(np.isfinite(world_from_listener)):
        return None
    L = listener_from_world(world_from_listener, frame)
    msg: dict[str, Any] = {"frame": frame, "waypoint": None, "obstacle": None, "stairs": None,
                           "has_path": False, "goal_reached": False, "feasible": False,
                           "proximity_range": s.proximity_range}
    if guidance is not None:
        msg["t"] = float(guidance.stamp) if math.isfinite(guidance.stamp) else 0.0
        msg["has_path"], msg["goal_reached"], msg["feasible"] = (bool(guidance.has_path), bool(guidance.goal_reached),
                                                                 bool(guidance.feasible))
        if "waypoint" in s.enabled and guidance.next_waypoint is not None and not guidance.goal_reached:
            wp = _point(L, [guidance.next_waypoint[0], guidance.next_waypoint[1], s.floor_height])
            msg["waypoint"] = None if wp is None else {"position": wp}
        distance = float(guidance.nearest_obstacle_distance)
        if "obstacle" in s.enabled and guidance.nearest_obstacle is not None and math.isfinite(distance):
            ob = _point(L, [guidance.nearest_obstacle[0], guidance.nearest_obstacle[1], s.floor_height])
            msg["obstacle"] = None if ob is None else {"position": ob, "distance": round(distance, 3)}
    if "stairs" in s.enabled and stairs is not None and float(stairs.distance) <= s.stairs_range:
        if listener_from_camera is None:
            listener_from_camera = np.eye(4)
            if frame == "head":
                listener_from_camera[:3, :3] = HEAD_FROM_CAMERA
        edge = _point(listener_from_camera, np.asarray(stairs.camera_from_stair, dtype=float)[:3, 3])
        if edge is not None:
            msg["stairs"] = {"position": edge, "distance": round(float(stairs.distance), 3),
                             "direction": "up" if int(stairs.direction) == 0 else "down"}
    return msg
