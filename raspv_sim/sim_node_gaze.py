"""The sim node's eye-gaze log (ROS side; the file is :meth:`raspv_sim.experiment_log.ExperimentLog.gaze`):
every ``/gaze/direction`` sample goes into the run's ``gaze.csv`` with the simulation time it
arrived at. Samples come at 60–1000 Hz, and a scripted subject in lockstep sends a frame's worth
at once: taken in the simulator's own executor, between its frames, they queued up behind the
stepping and rendering (a trial's last second never reached its log). So they are taken by a lean
node of their own (one subscription, no parameter services) spun in a thread of its own, as the
bridge's frames are (:mod:`raspv_common.side_executor`). A mixin of :class:`raspv_sim.sim_node.SimNode`.
"""
from __future__ import annotations

import math

from geometry_msgs.msg import Vector3Stamped

from raspv_common import topics
from raspv_common.conversions import stamp_to_seconds
from raspv_common.qos import GAZE_QOS
from raspv_common.side_executor import SideExecutor


class SimGazeLog:
    """Eye-gaze samples into the run log (see the module docstring)."""

    def _setup_gaze_log(self) -> None:
        self._gaze_side = SideExecutor(self, "gaze", "sim-gaze", lambda node: node.create_subscription(
            Vector3Stamped, topics.GAZE_DIRECTION, self.on_gaze, GAZE_QOS))

    def on_gaze(self, msg: Vector3Stamped) -> None:
        log, v = self.sim.log, msg.vector
        if log is None:
            return
        direction = (v.x, v.y, v.z)
        norm = math.sqrt(sum(c * c for c in direction))
        valid = all(math.isfinite(c) for c in direction) and norm > 1e-9
        log.gaze(self.sim.t, stamp_to_seconds(msg.header.stamp), tuple(c / norm for c in direction) if valid else None)

    def _close_gaze_log(self) -> None:
        side = getattr(self, "_gaze_side", None)
        if side is not None:
            side.close()
