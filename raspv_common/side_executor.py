"""A lean node spun by an executor of its own in a thread (ROS side): for a high-rate input that
must not wake a busy node's executor. rclpy's executor cost per wake-up grows with the entities it
waits on (all of a node's subscriptions, services, timers and clients): a 120 Hz gaze stream taken
by the spv node's own executor slowed its display; taken by a node holding one subscription, in a
thread of its own, it costs a fraction. (:mod:`raspv_hmd.bridge_frames` does the same for the
bridge's frames.)
"""
from __future__ import annotations

import threading
from typing import Callable

import rclpy
from rclpy.node import Node
from rclpy.executors import SingleThreadedExecutor

from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown


class SideExecutor:
    """``node``: a lean node ``<owner>_<suffix>`` (no parameter services, no rosout) in the owner's
    context, spun by its own executor in thread ``thread_name``; ``setup(node)`` creates its
    entities before the thread starts (a wait already under way would see new ones only at its
    next turn); :meth:`close` stops both."""

    def __init__(self, owner, suffix: str, thread_name: str, setup: Callable[[Node], None]) -> None:
        self._context = owner.context
        self.node = rclpy.create_node(f"{owner.get_name()}_{suffix}", context=owner.context,
                                      start_parameter_services=False, enable_rosout=False)
        setup(self.node)
        self._executor = SingleThreadedExecutor(context=owner.context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name=thread_name, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            while self._context.ok():
                self._executor.spin_once(timeout_sec=0.5)
        except SHUTDOWN_ERRORS as exc:              # shutting down; any other error is a bug and shows
            if not during_shutdown(exc, self._context):
                raise

    def close(self) -> None:
        """Stop the thread, then destroy the node (never while its executor waits on it)."""
        self._executor.shutdown(timeout_sec=1.0)
        self._thread.join(timeout=2.0)
        if not self._thread.is_alive():
            self.node.destroy_node()
