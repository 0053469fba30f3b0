"""Whether the viewer's head turns the camera (no ROS): decided from where the images come from.

Display-time reprojection (:mod:`raspv_spv.reprojection`) re-samples the last camera frame for the
newest ``/head/orientation``. That is right only when the viewer's head turns the camera: the
simulator's camera on the avatar's head, or a real camera mounted on the viewer's head. A
recording (a replayed bag, a camera node playing a file) was turned by the head of whoever
recorded it, and a camera on the chest, in the hand or on a robot is not turned by the head at
all: dragging in the browser (or turning a headset) must never move their phosphenes. The
launcher derives the spv node's ``camera_source`` from the graph's source node
(:func:`camera_source_of`); the display view follows the head only for :func:`head_turns_camera`.
"""
from __future__ import annotations

# Where the images come from (spv ``camera_source``), and whether the viewer's head turns that camera.
CAMERA_SOURCES: dict[str, bool] = {
    "sim": True,          # the simulator's camera on the avatar's head, turned by /head/orientation
    "head": True,         # a real camera mounted on the viewer's head
    "chest": False, "hand": False, "robot": False, "custom": False,   # real cameras carried elsewhere
    "recording": False,   # a replayed bag or a recording played by the camera node: its head was someone else's
    "unknown": False,     # nothing says the camera is on the viewer's head: never turn it
}


def head_turns_camera(camera_source: str) -> bool:
    """Whether ``/head/orientation`` turns the camera of ``camera_source`` (a :data:`CAMERA_SOURCES`
    key), i.e. whether display-time reprojection may follow the viewer's head."""
    if camera_source not in CAMERA_SOURCES:
        raise ValueError(f"unknown camera source {camera_source!r}; expected {', '.join(CAMERA_SOURCES)}")
    return CAMERA_SOURCES[camera_source]


def camera_source_of(source_kind: str, file: str = "", mounting: str = "head") -> str:
    """The :data:`CAMERA_SOURCES` key of a graph's image source: node kind ``sim``, ``camera`` (a
    live device, or ``file`` a recording it plays; ``mounting`` the scene node's) or ``replay``."""
    if source_kind == "sim":
        return "sim"
    if source_kind == "replay" or (source_kind == "camera" and file):
        return "recording"
    if source_kind == "camera":
        return mounting if mounting in CAMERA_SOURCES else "unknown"
    return "unknown"
