"""The spv node's eye gaze (ROS side; the algorithms are :mod:`raspv_spv.gaze`): subscribes
``/gaze/direction`` (geometry_msgs/Vector3Stamped, head frame, a zero vector = invalid sample)
while ``gaze_mode`` is not ``ignored``, shows a visible gaze change at once through the display's
display-on-input path (as a head turn), and tells each display tick where the field goes, whether
the sampling turns with the eye and whether a saccade blanks it. ``gaze_mode``,
``saccade_display`` and ``saccade_threshold`` change at run time without rebuilding anything.

Gaze samples come at 60–1000 Hz. Taken by the spv node's own executor, every sample was a
wake-up of a wait set holding all its subscriptions, services and timers (the cost the bridge's
frames avoid the same way, :mod:`raspv_hmd.bridge_frames`): the gaze step's display onset had a
p95 4× a head turn's. So they are taken by a lean node of their own (one subscription, no
parameter services) spun by its own executor in a thread (:mod:`raspv_common.side_executor`). A mixin of :class:`raspv_spv.spv_node.SpvNode`.
"""
from __future__ import annotations

import time

from geometry_msgs.msg import Vector3Stamped

from raspv_common import topics
from raspv_common.conversions import stamp_to_seconds
from raspv_common.qos import SENSOR_QOS
from raspv_common.side_executor import SideExecutor
from raspv_spv.gaze import NO_GAZE, GazeDisplay, GazeError, GazeTracker, gaze_display

GAZE_PARAMS = frozenset({"gaze_mode", "saccade_display", "saccade_threshold"})


class SpvGaze:
    """Eye gaze of the spv node (see the module docstring)."""

    def _setup_gaze(self) -> None:
        self.gaze = GazeTracker(self.params["saccade_threshold"])
        self._gaze_params = {k: self.params[k] for k in GAZE_PARAMS}    # applied at once (params follow later)
        self._gaze_sub = None
        self._gaze_side = SideExecutor(self, "gaze", "spv-gaze", self._setup_gaze_node)

    def _setup_gaze_node(self, node) -> None:
        self._gaze_node = node
        self._gaze_follow = node.create_guard_condition(self._follow_gaze_mode)
        self._gaze_follow.trigger()                 # subscribes (or not) as soon as the thread spins

    def _close_gaze(self) -> None:
        side = getattr(self, "_gaze_side", None)
        if side is not None:
            side.close()

    def _follow_gaze_mode(self) -> None:
        """Subscribe to the gaze while it is used, and only then (in the gaze thread)."""
        mode = self._gaze_params["gaze_mode"]
        if mode != "ignored" and self._gaze_sub is None:
            self._gaze_sub = self._gaze_node.create_subscription(Vector3Stamped, topics.GAZE_DIRECTION, self.on_gaze,
                                                                 SENSOR_QOS)
        elif mode == "ignored" and self._gaze_sub is not None:
            self._gaze_node.destroy_subscription(self._gaze_sub)
            self._gaze_sub = None

    def apply_gaze_params(self, changes: dict) -> bool:
        """Apply the gaze parameters among accepted ``changes``; True when there was nothing else
        (nothing to rebuild)."""
        changes = {k: v for k, v in changes.items() if k in GAZE_PARAMS} if changes else {}
        if not changes:
            return False
        self._gaze_params.update(changes)
        if "saccade_threshold" in changes:
            self.gaze.threshold = float(changes["saccade_threshold"])
        if "gaze_mode" in changes:
            self._gaze_follow.trigger()
        self._applied_params.update(changes)
        self.clock.poke()                           # the field moves (or comes back) at once
        return True

    def on_gaze(self, msg: Vector3Stamped) -> None:
        v = msg.vector
        valid = (v.x, v.y, v.z) != (0.0, 0.0, 0.0)
        try:
            show_now = self.gaze.add(stamp_to_seconds(msg.header.stamp), (v.x, v.y, v.z), valid, time.monotonic())
        except GazeError as exc:
            self.warn_throttled("gaze", f"ignoring {topics.GAZE_DIRECTION}: {exc}")
            return
        if show_now:
            self.clock.poke()                       # shown now, not at the next tick (like a head turn)

    def gaze_for_tick(self, sim) -> GazeDisplay:
        """Where this display frame draws the field and how it samples (:func:`raspv_spv.gaze.gaze_display`;
        the sampling rotation goes to the display view, :attr:`raspv_spv.reprojection.DisplayView.gaze_rotation`).
        The no-data ring moves with the eye too: it is on the same display."""
        p = self._gaze_params
        shown = NO_GAZE if p["gaze_mode"] == "ignored" else gaze_display(
            p["gaze_mode"], p["saccade_display"], self.gaze.state(time.monotonic()), sim.map.focal_px)
        self.view.gaze_rotation = shown.sampling_rotation     # contingent: the display's sampling turns with the eye
        return shown
