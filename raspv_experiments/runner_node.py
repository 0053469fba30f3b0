"""The experiment runner's connection to the running graph: an rclpy node in the runner's process
(thin: it only moves data between ROS and :mod:`raspv_experiments.session_runner`).

It follows the simulation time (``/clock``), the avatar (``/odom``), collisions
(``/sim/collisions``), the subject's start/abort (``/experiment/response``), what the display
showed (``/spv/frame``: mode and overlays of each frame) and the phosphene map (``/spv/map``:
how many phosphenes were shown); it shows
instructions (``/experiment/instructions``, latched JSON ``{id, trial, title, text, waiting}``),
calls the simulator's trial services and sets node parameters.
"""
from __future__ import annotations

import json
import os
import threading
import time
from collections import deque
from typing import Any

from raspv_common import topics


class RunnerError(Exception):
    """The graph did not answer or refused a request; the message says which and why."""


class GraphClient:
    def __init__(self, name: str = "raspv_experiment") -> None:
        import rclpy
        from nav_msgs.msg import Odometry
        from raspv_msgs.msg import CollisionEvent, PhospheneFrame, PhospheneMap
        from raspv_msgs.srv import EndTrial, StartTrial
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        from std_msgs.msg import String

        from raspv_common.qos import COMMAND_QOS, EVENT_QOS, LATCHED_QOS, SENSOR_QOS

        self._rclpy = rclpy
        self._String = String
        self._StartTrial, self._EndTrial = StartTrial, EndTrial
        self.context = rclpy.Context()
        rclpy.init(context=self.context, args=["runner", "--ros-args", "--disable-rosout-logs"])
        self.node = rclpy.create_node(f"{name}_{os.getpid()}", context=self.context)
        self.lock = threading.Lock()
        self.sim_time: float | None = None
        self.clock_wall = time.monotonic()
        self.pose: tuple[float, float] | None = None
        self.collision_events: deque[dict[str, Any]] = deque()
        self.responses: deque[dict[str, Any]] = deque()
        self.frames: list = []                      # ShownFrame of every /spv/frame since take_frames
        self.map_info: dict[str, Any] = {}
        n = self.node
        n.create_subscription(Clock, topics.CLOCK, self._on_clock, COMMAND_QOS)
        n.create_subscription(Odometry, topics.ODOM, self._on_odom, SENSOR_QOS)
        n.create_subscription(CollisionEvent, topics.SIM_COLLISIONS, self._on_collision, EVENT_QOS)
        n.create_subscription(String, topics.EXPERIMENT_RESPONSE, self._on_response, EVENT_QOS)
        # every frame counts for the share shown (raspv_common.shown_share): a deep reader queue
        n.create_subscription(PhospheneFrame, topics.SPV_FRAME, self._on_frame,
                              QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=500, reliability=ReliabilityPolicy.RELIABLE))
        n.create_subscription(PhospheneMap, topics.SPV_MAP, self._on_map, LATCHED_QOS)
        self.pub_instructions = n.create_publisher(String, topics.EXPERIMENT_INSTRUCTIONS, LATCHED_QOS)
        self.start_client = n.create_client(StartTrial, topics.SIM_START_TRIAL)
        self.end_client = n.create_client(EndTrial, topics.SIM_END_TRIAL)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(n)
        self._thread = threading.Thread(target=self._spin, daemon=True, name="runner-ros")
        self._thread.start()

    def _spin(self) -> None:
        from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown

        try:
            self.executor.spin()
        except SHUTDOWN_ERRORS as exc:               # the context was shut down: the spin ends
            if not during_shutdown(exc, self.context):
                raise

    def close(self) -> None:
        try:
            self.executor.shutdown(timeout_sec=2.0)
            self.node.destroy_node()
        finally:
            self._rclpy.try_shutdown(context=self.context)
            self._thread.join(timeout=3.0)

    # -- inputs ---------------------------------------------------------------------------------
    def _on_clock(self, msg) -> None:
        t = msg.clock.sec + msg.clock.nanosec * 1e-9
        with self.lock:
            if self.sim_time is None or t != self.sim_time:
                self.clock_wall = time.monotonic()
            self.sim_time = t

    def _on_odom(self, msg) -> None:
        p = msg.pose.pose.position
        with self.lock:
            self.pose = (float(p.x), float(p.y))

    def _on_collision(self, msg) -> None:
        with self.lock:
            self.collision_events.append({"name": msg.other_name, "class": msg.other_class, "count": int(msg.count)})

    def _on_response(self, msg) -> None:
        try:
            data = json.loads(msg.data)
        except json.JSONDecodeError:
            return
        if isinstance(data, dict):
            with self.lock:
                self.responses.append(data)

    def _on_frame(self, msg) -> None:
        from raspv_common.shown_share import ShownFrame

        h = msg.header.stamp
        frame = ShownFrame(h.sec + 1e-9 * h.nanosec, msg.mode, tuple(msg.overlays), msg.configured_mode,
                           tuple(msg.configured_overlays))
        with self.lock:
            self.frames.append(frame)

    def _on_map(self, msg) -> None:
        shown = int(len(msg.x) - sum(bool(d) for d in msg.dropped))
        with self.lock:
            self.map_info = {"device": msg.device, "map_id": int(msg.map_id), "phosphenes": int(len(msg.x)),
                             "phosphenes_shown": shown}

    def wait_frame(self, stamp: float, timeout: float = 10.0) -> bool:
        """Wait until a frame stamped ``stamp`` [s] or later arrived (the display's last frame of a
        trial comes after the simulator's clock and pose of it); False on timeout."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                if self.frames and self.frames[-1].t >= stamp - 1e-6:
                    return True
            time.sleep(0.005)
        return False

    def take_frames(self) -> list:
        """The /spv/frame frames (ShownFrame) since the last call."""
        with self.lock:
            out, self.frames = self.frames, []
            return out

    def display_map(self) -> dict[str, Any]:
        """The phosphene map on display: device, map id, phosphenes (and those not dropped out)."""
        with self.lock:
            return dict(self.map_info)

    def state(self) -> tuple[float | None, tuple[float, float] | None, float]:
        """(sim time [s], base (x, y) [m, W], wall seconds since the sim time last changed)."""
        with self.lock:
            return self.sim_time, self.pose, time.monotonic() - self.clock_wall

    def take_collisions(self) -> list[dict[str, Any]]:
        with self.lock:
            out = list(self.collision_events)
            self.collision_events.clear()
            return out

    def take_responses(self) -> list[dict[str, Any]]:
        with self.lock:
            out = list(self.responses)
            self.responses.clear()
            return out

    # -- requests -------------------------------------------------------------------------------
    def wait_ready(self, nodes: list[str], timeout: float, alive=lambda: True) -> None:
        """Wait until the simulator's trial services, the parameter services of ``nodes`` and
        the simulation clock are up."""
        from raspv_common.param_client import ParamClient

        clients = [ParamClient(self.node, n) for n in nodes]
        deadline = time.monotonic() + timeout
        try:
            while True:
                missing = [c.target for c in clients if not c.is_ready()]
                if not self.start_client.service_is_ready():
                    missing.append(topics.SIM_START_TRIAL)
                if self.state()[0] is None:
                    missing.append(topics.CLOCK)
                if not missing:
                    return
                if not alive():
                    raise RunnerError("the graph stopped while starting (see the graph log)")
                if time.monotonic() > deadline:
                    raise RunnerError(f"the graph did not come up within {timeout:.0f} s: waiting for {', '.join(missing)}")
                time.sleep(0.05)
        finally:
            for c in clients:
                c.destroy()

    def wait_connected(self, required: dict[str, tuple[int, int]], timeout: float, settle_s: float = 1.0,
                       alive=lambda: True) -> None:
        """Wait until every topic in ``required`` has at least (publishers, subscribers) and the
        graph's endpoints, as this node sees them, stayed the same for ``settle_s``: a frame
        published before discovery finished is lost, and in lockstep a lost first frame would
        make a run differ from the next (see docs/DEVELOPING.md, the races tests avoid)."""
        deadline = time.monotonic() + timeout
        last, since = None, time.monotonic()
        while True:
            names = sorted(n for n, _ in self.node.get_topic_names_and_types())
            now = tuple((n, self.node.count_publishers(n), self.node.count_subscribers(n)) for n in names)
            counts = {n: (p, s) for n, p, s in now}
            missing = [t for t, (p, s) in required.items() if counts.get(t, (0, 0))[0] < p or counts.get(t, (0, 0))[1] < s]
            if now != last:
                last, since = now, time.monotonic()
            elif not missing and time.monotonic() - since >= settle_s:
                return
            if not alive():
                raise RunnerError("the graph stopped while starting (see the graph log)")
            if time.monotonic() > deadline:
                raise RunnerError(f"the graph's topics did not connect within {timeout:.0f} s: "
                                  + (", ".join(missing) if missing else "its endpoints kept changing"))
            time.sleep(0.05)

    def _wait(self, future, timeout: float, what: str):
        deadline = time.monotonic() + timeout
        while not future.done():
            if time.monotonic() > deadline:
                raise RunnerError(f"{what}: no answer within {timeout:.0f} s")
            time.sleep(0.005)
        if future.result() is None:
            raise RunnerError(f"{what}: failed ({future.exception()})")
        return future.result()

    def set_params(self, node: str, values: dict[str, Any], timeout: float = 20.0) -> None:
        """Set parameters of ``node`` (all at once); RunnerError naming what was refused and why."""
        from raspv_common.param_client import ParamClient

        if not values:
            return
        client = ParamClient(self.node, node)
        try:
            ok, answer = client.ask_until_answered(lambda done: client.set_async(values, done), timeout)
        finally:
            client.destroy()
        if not ok:
            raise RunnerError(f"node {node}: {answer}")
        refused = [f"{name}: {reason}" for name, ok, reason in answer if not ok]
        if refused:
            raise RunnerError(f"node {node} refused {'; '.join(refused)}")

    def start_trial(self, x: float, y: float, yaw: float, goal: tuple[str, float, float, float],
                    log_dir: str = "", run_name: str = "", timeout: float = 30.0, time_limit: float = 0.0):
        req = self._StartTrial.Request(x=float(x), y=float(y), yaw=float(yaw), goal_name=goal[0], goal_x=float(goal[1]),
                                       goal_y=float(goal[2]), goal_radius=float(goal[3]), log_dir=log_dir,
                                       run_name=run_name, time_limit=float(time_limit))
        res = self._wait(self.start_client.call_async(req), timeout, "starting the trial in the simulator")
        if not res.success:
            raise RunnerError(f"the simulator refused the trial: {res.message}")
        with self.lock:
            self.collision_events.clear()
        return res

    def end_trial(self, plot: bool = False, timeout: float = 60.0) -> tuple[dict[str, Any], float]:
        res = self._wait(self.end_client.call_async(self._EndTrial.Request(plot=plot)), timeout,
                         "ending the trial in the simulator")
        return (json.loads(res.summary_json) if res.summary_json else {}), float(res.sim_time)

    def show(self, info: dict[str, Any]) -> None:
        """Publish instructions (latched) for the headset client and scripted subjects."""
        self.pub_instructions.publish(self._String(data=json.dumps(info)))
