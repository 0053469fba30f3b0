"""The sim node's eye-gaze log (ROS side; the file is :meth:`raspv_sim.experiment_log.ExperimentLog.gaze`):
every ``/gaze/direction`` sample goes into the run's ``gaze.csv`` with the simulation time it
arrived at. Samples come at 60–1000 Hz, and a scripted subject in lockstep sends a frame's worth
at once: taken in the simulator's own executor, between its frames, they queued up behind the
stepping and rendering (a trial's last second never reached its log). So they are taken by a lean
node of their own (one subscription, no parameter services) spun in a thread of its own, as the
bridge's frames are. A mixin of :class:`raspv_sim.sim_node.SimNode`.
"""
from __future__ import annotations

import math
import threading

import rclpy
from geometry_msgs.msg import Vector3Stamped
from rclpy.executors import ExternalShutdownException, ShutdownException, SingleThreadedExecutor

from raspv_common import topics
from raspv_common.conversions import stamp_to_seconds
from raspv_common.qos import GAZE_QOS


class SimGazeLog:
    """Eye-gaze samples into the run log (see the module docstring)."""

    def _setup_gaze_log(self) -> None:
        self._gaze_node = rclpy.create_node(f"{self.get_name()}_gaze", context=self.context,
                                            start_parameter_services=False, enable_rosout=False)
        self._gaze_node.create_subscription(Vector3Stamped, topics.GAZE_DIRECTION, self.on_gaze, GAZE_QOS)
        self._gaze_executor = SingleThreadedExecutor(context=self.context)
        self._gaze_executor.add_node(self._gaze_node)
        self._gaze_thread = threading.Thread(target=self._spin_gaze, name="sim-gaze", daemon=True)
        self._gaze_thread.start()

    def _spin_gaze(self) -> None:
        try:
            while self.context.ok():
                self._gaze_executor.spin_once(timeout_sec=0.5)
        except (ExternalShutdownException, ShutdownException, RuntimeError):
            pass                                    # shutting down

    def on_gaze(self, msg: Vector3Stamped) -> None:
        log, v = self.sim.log, msg.vector
        if log is None:
            return
        direction = (v.x, v.y, v.z)
        norm = math.sqrt(sum(c * c for c in direction))
        valid = all(math.isfinite(c) for c in direction) and norm > 1e-9
        log.gaze(self.sim.t, stamp_to_seconds(msg.header.stamp), tuple(c / norm for c in direction) if valid else None)

    def _close_gaze_log(self) -> None:
        executor = getattr(self, "_gaze_executor", None)
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
            self._gaze_thread.join(timeout=2.0)
            if not self._gaze_thread.is_alive():
                self._gaze_node.destroy_node()
