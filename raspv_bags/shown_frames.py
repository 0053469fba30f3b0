"""What the wearer saw in a recording: the ``/spv/frame`` messages of a bag as
:class:`~raspv_common.shown_share.ShownFrame`, and their share in the configured representation
(no ROS imports; ``raspv bag info`` prints it).

Recordings made before ``PhospheneFrame`` had ``configured_mode`` / ``configured_overlays`` (or the
gaze fields ``field_offset_x_px`` / ``field_offset_y_px`` / ``saccade``) are
decoded with the definition stored in the bag (registered under a private alias, so the current
one is untouched); their expected mode is then inferred as the most frequent mode shown other
than ``no_data`` (:func:`raspv_common.shown_share.shown_share` says so).
"""
from __future__ import annotations

import hashlib
import re

from raspv_bags.message_types import normalise_type, typestore
from raspv_common.shown_share import ShownFrame, ShownShare, shown_share

FRAME_TOPIC = "/spv/frame"
FRAME_TYPE = "raspv_msgs/msg/PhospheneFrame"
LEGACY_ALIAS = "raspv_bags_recorded/msg/PhospheneFrame"    # the bag's own definition, when it predates ours
CURRENT_FIELDS = ("configured_mode", "field_offset_x_px", "saccade")   # the newest fields, by version


def _decode_type(definition: str) -> str:
    """The type to decode with: ours, or the bag's stored definition when it lacks a field of ours
    (recorded before ``configured_mode``, or before the gaze fields ``field_offset_*`` and
    ``saccade``), registered under an alias named by the definition's hash."""
    own = definition.split("=" * 80)[0]
    if not definition or all(re.search(rf"\b{name}\b", own) for name in CURRENT_FIELDS):
        return FRAME_TYPE
    alias = f"{LEGACY_ALIAS}{hashlib.sha1(definition.encode()).hexdigest()[:10]}"
    store = typestore()
    if alias not in store.fielddefs:
        from raspv_bags.message_types import _types_from_concatenated_msg

        store.register(_types_from_concatenated_msg(definition, alias))
    return alias


def shown_frames(reader, topic: str = FRAME_TOPIC) -> list[ShownFrame]:
    """Every frame of ``topic`` in an open :class:`~raspv_bags.reader.BagReader` (display stamps)."""
    info = reader.topics.get(topic)
    if info is None or normalise_type(info.msgtype) != FRAME_TYPE:
        return []
    msgtype = _decode_type(info.definition)
    store = typestore()
    out = []
    for m in reader.messages([topic]):
        msg = store.deserialize_cdr(bytes(m.data), msgtype)
        stamp = msg.header.stamp
        out.append(ShownFrame(stamp.sec + 1e-9 * stamp.nanosec, msg.mode, tuple(msg.overlays),
                              getattr(msg, "configured_mode", ""), tuple(getattr(msg, "configured_overlays", ()))))
    return out


def bag_shown_share(reader, topic: str = FRAME_TOPIC) -> ShownShare | None:
    """The share of the bag's frames shown in the configured representation (None: no such topic)."""
    frames = shown_frames(reader, topic)
    return shown_share(frames) if frames else None
