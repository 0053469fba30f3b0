"""Serialised messages of a changing set of topics, taken on a thread of their own (ROS side).

A viewer bridge (the ``foxglove`` node) forwards 100–200 messages a second, most of them images,
without looking inside them. Through rclpy's executor each message cost about a millisecond of
CPU on this machine, half of it the executor's own Python: it rebuilds its wait set from every
entity of the node (services, timers, QoS-event handlers) and runs one callback per wait. Here
the subscriptions live on a node of their own that no executor spins; one thread waits on them
(and on a guard condition that tells it the set changed) and takes *every* ready message of every
topic per wake, passing the CDR bytes to the topic's callback.

It uses rclpy's wait-set binding (``rclpy_implementation.WaitSet``), as the executor does; rclpy
has no public wait set. The subscriptions carry no QoS-event handlers.
"""
from __future__ import annotations

import threading
from typing import Any, Callable

import rclpy
from rclpy.context import Context
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import QoSProfile

WAIT_NS = 200_000_000          # the thread looks at its stop flag at least this often [ns]


class RawForwarder:
    """``set_topics({topic: (message class, QoS, callback(bytes))})`` from any thread (a topic's
    subscription is kept while its class is; its QoS is the one it was first asked with); the
    callbacks run on the forwarder's thread, in arrival order per topic."""

    def __init__(self, context: Context, name: str) -> None:
        self.node = rclpy.create_node(name, context=context, use_global_arguments=False,
                                      start_parameter_services=False, enable_rosout=False)
        self._context = context
        self._wanted: dict[str, tuple[type, QoSProfile, Callable[[bytes], None]]] = {}
        self._subs: dict[str, tuple[Any, Callable[[bytes], None]]] = {}
        self._lock = threading.Lock()
        self._changed = True
        self._stop = False
        self._wake = self.node.create_guard_condition(lambda: None)
        self._thread = threading.Thread(target=self._run, name=f"{name}-take", daemon=True)
        self._thread.start()

    def set_topics(self, wanted: dict[str, tuple[type, QoSProfile, Callable[[bytes], None]]]) -> None:
        with self._lock:
            self._wanted = dict(wanted)
            self._changed = True
        self._wake.trigger()

    def close(self, timeout: float = 2.0) -> None:
        self._stop = True
        try:
            self._wake.trigger()
        except Exception:  # noqa: BLE001 - the context is already shut down
            pass
        self._thread.join(timeout)
        if not self._thread.is_alive():
            self.node.destroy_node()

    # -- the forwarder's thread ----------------------------------------------------------------
    def _apply(self) -> None:
        """Create and destroy subscriptions (on this thread: none is destroyed while waited on)."""
        with self._lock:
            wanted, self._changed = dict(self._wanted), False
        for topic in [t for t, (sub, _) in self._subs.items() if t not in wanted or wanted[t][0] is not sub.msg_type]:
            sub, _ = self._subs.pop(topic)
            self.node.destroy_subscription(sub)
        for topic, (msg_class, qos, callback) in wanted.items():
            sub = self._subs[topic][0] if topic in self._subs else self.node.create_subscription(
                msg_class, topic, lambda _m: None, qos, raw=True,
                event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
            self._subs[topic] = (sub, callback)

    def _run(self) -> None:
        wait_set = None
        entries: list[tuple[Any, Callable[[bytes], None]]] = []
        try:
            while not self._stop and self._context.ok():
                if self._changed or wait_set is None:
                    self._apply()
                    entries = list(self._subs.values())
                    wait_set = _rclpy.WaitSet(len(entries), 1, 0, 0, 0, 0, self._context.handle)
                wait_set.clear_entities()
                for sub, _ in entries:
                    wait_set.add_subscription(sub.handle)
                wait_set.add_guard_condition(self._wake.handle)
                wait_set.wait(WAIT_NS)
                ready = wait_set.get_ready_entities("subscription")
                if not ready:
                    continue
                for sub, callback in entries:
                    if sub.handle.pointer not in ready:
                        continue
                    while True:                     # every message waiting, not one per wake
                        taken = sub.handle.take_message(sub.msg_type, True)
                        if taken is None:
                            break
                        callback(taken[0])
        except Exception:  # noqa: BLE001 - the context shut down under the wait (process stopping)
            if self._context.ok() and not self._stop:
                raise
