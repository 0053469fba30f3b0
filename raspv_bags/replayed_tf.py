"""What a replay publishes on /tf and /tf_static from a recording (no ROS imports).

- ``/tf``: the recording's transforms, less those a pose node of the replaying graph owns
  (``exclude_children``: e.g. ``odom`` and ``base_link`` when a slam node re-estimates the pose;
  a sim recording keeps its head joint ``base_link → head``).
- ``/tf_static``: a recording holds one static message per node that published one (sim,
  camera, …); a replay has one transient-local publisher of depth 1, so it sends the union of
  every static transform seen so far each time, as one node would.
- A recording without ``/tf_static`` (made before tf, or imported from a dataset) gets the
  camera's mounting chain ``base_link → camera_link → <its images' frame>``
  (:func:`raspv_common.frames.camera_mounting_edges`: the camera is the body).

Messages are (de)serialised with the bags' rosbags typestore (CDR), so this runs with or without rclpy.
"""
from __future__ import annotations

from typing import Any, Iterable

import numpy as np

from raspv_bags.message_types import typestore
from raspv_common.frames import camera_mounting_edges
from raspv_common.rotations import matrix_to_quaternion

TF_TYPE = "tf2_msgs/msg/TFMessage"


def _transform(parent: str, child: str, T: np.ndarray, stamp_ns: int) -> Any:
    store = typestore()
    types = store.types
    qx, qy, qz, qw = matrix_to_quaternion(T[:3, :3])
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                          frame_id=parent)
    transform = types["geometry_msgs/msg/Transform"](
        translation=types["geometry_msgs/msg/Vector3"](x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3])),
        rotation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw))
    return types["geometry_msgs/msg/TransformStamped"](header=header, child_frame_id=child, transform=transform)


def header_frame_id(data: bytes, msgtype: str) -> str:
    """The ``header.frame_id`` of a serialised message that has a header (an image, camera info)."""
    return typestore().deserialize_cdr(bytes(data), msgtype).header.frame_id


class ReplayedTf:
    """Filters and merges a recording's transforms for republishing (serialised CDR in and out)."""

    def __init__(self, exclude_children: Iterable[str] = ()) -> None:
        self.exclude = frozenset(c for c in exclude_children if c)
        self._static: dict[str, Any] = {}          # child frame → TransformStamped, the union so far

    def _decode(self, data: bytes) -> list[Any]:
        return list(typestore().deserialize_cdr(bytes(data), TF_TYPE).transforms)

    def _encode(self, transforms: list[Any]) -> bytes:
        store = typestore()
        return bytes(store.serialize_cdr(store.types[TF_TYPE](transforms=transforms), TF_TYPE))

    def tf(self, data: bytes) -> bytes | None:
        """A recorded /tf message without the excluded transforms (None: nothing left to send)."""
        if not self.exclude:
            return data
        kept = [t for t in self._decode(data) if t.child_frame_id not in self.exclude]
        return self._encode(kept) if kept else None

    def tf_static(self, data: bytes) -> bytes | None:
        """The union of static transforms after adding a recorded /tf_static message (None: it
        added nothing new and the union was sent already)."""
        added = False
        for t in self._decode(data):
            if t.child_frame_id not in self.exclude:
                self._static[t.child_frame_id] = t
                added = True
        return self._encode(list(self._static.values())) if added or not self._static else None

    def mounting(self, optical_frame: str, stamp_ns: int) -> bytes:
        """The camera mounting chain of a recording without /tf_static, added to the union."""
        for parent, child, T in camera_mounting_edges(optical_frame):
            if child not in self.exclude:
                self._static[child] = _transform(parent, child, T, stamp_ns)
        return self._encode(list(self._static.values()))

    def static_children(self) -> set[str]:
        return set(self._static)
