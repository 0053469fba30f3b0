"""Graph introspection helpers shared by the CLI and the test harness.

Resolve message types from their names, convert messages to plain Python for printing, pick a
QoS that matches a topic's publishers, and wait for discovery to settle.
"""
from __future__ import annotations

import importlib
import time
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def message_class(type_name: str) -> type:
    """``"sensor_msgs/msg/Image"`` (or ``sensor_msgs/Image``) → the message class."""
    parts = type_name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"not a message type name: {type_name!r} (expected pkg/msg/Name)")
    pkg, kind, name = parts
    try:
        module = importlib.import_module(f"{pkg}.{kind}")
        return getattr(module, name)
    except (ImportError, AttributeError):
        raise ValueError(f"message type {type_name!r} is not installed") from None


def message_to_plain(msg: Any, max_array: int | None = 16) -> Any:
    """A message → nested dicts/lists. Arrays longer than ``max_array`` are shortened to their
    first items plus a ``"... (N items)"`` marker (``None`` keeps everything)."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {name: message_to_plain(getattr(msg, name), max_array) for name in msg.get_fields_and_field_types()}
    if isinstance(msg, (bytes, bytearray)):
        msg = list(msg)
    if isinstance(msg, (list, tuple)) or type(msg).__name__ in ("array", "ndarray"):
        items = list(msg)
        if max_array is not None and len(items) > max_array:
            return [message_to_plain(x, max_array) for x in items[:max_array]] + [f"... ({len(items)} items)"]
        return [message_to_plain(x, max_array) for x in items]
    if hasattr(msg, "item"):  # numpy scalar
        return msg.item()
    return msg


def qos_matching_publishers(node: Node, topic: str) -> QoSProfile:
    """A subscription QoS compatible with every current publisher of ``topic`` (like ``ros2``):
    reliable only if all are reliable; transient-local only if all are."""
    infos = node.get_publishers_info_by_topic(topic)
    reliable = bool(infos) and all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
    latched = bool(infos) and all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def wait_for_topic_type(node: Node, topic: str, timeout_s: float) -> str | None:
    """The type name of ``topic`` once it is discovered, or None after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        for name, types in node.get_topic_names_and_types():
            if name == topic and types:
                return types[0]
        if time.monotonic() >= deadline:
            return None
        time.sleep(0.05)


def other_nodes(node: Node) -> list[str]:
    """Names of the discovered nodes other than ``node`` itself."""
    me = (node.get_name(), node.get_namespace())
    return [n for n, ns in node.get_node_names_and_namespaces() if (n, ns) != me]


def settled_topics(node: Node, max_wait_s: float = 5.0, quiet_s: float = 0.7) -> list[tuple[str, list[str]]]:
    """Topic names and types once another node has been discovered and the list has not changed
    for ``quiet_s`` seconds (discovery takes 0–1.7 s here, more under load), at most
    ``max_wait_s``. Our own topics appear at once, so they alone never count as settled."""
    start = time.monotonic()
    deadline = start + max_wait_s
    last = None
    last_change = start
    while time.monotonic() < deadline:
        now = sorted((n, sorted(t)) for n, t in node.get_topic_names_and_types())
        if now != last:
            last, last_change = now, time.monotonic()
        elif time.monotonic() - last_change >= quiet_s and other_nodes(node):
            break
        time.sleep(0.05)
    return last or []
