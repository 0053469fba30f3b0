"""`bridge` node: the headset server (raspv_hmd/server.py) in the graph.

Streams the spv node's frames to headset clients — the levels stream to clients that draw the
sprites themselves (the browser client), ``/spv/image`` (mono8 or rgb8) to the others, and the
no-data ring while the spv node is gone (:mod:`raspv_hmd.bridge_frames`); publishes the
controlling client's head as ``/head/orientation`` (QuaternionStamped, frame ``base``, head
relative to the base, identity looks ahead) and its teleop as ``/cmd_vel`` (Twist, clamped to
``max_linear``/``max_angular``; one zero twist after ``deadman_timeout`` without input); turns
the viewer keys (raspv_hmd/keymap.py) and direct parameter requests into parameter changes of
the ``spv`` node and tells the client the result. Experiments: shows ``/experiment/instructions``
in the clients and publishes the subject's start/abort on ``/experiment/response``. Prints the
client URL at start-up.
"""
from __future__ import annotations

import collections
import dataclasses
import json
import threading
import time
from typing import Any, Callable

from geometry_msgs.msg import Quaternion, QuaternionStamped, Twist, Vector3, Vector3Stamped
from std_msgs.msg import String

from raspv_common import topics
from raspv_common.frames import BASE_LINK
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.param_client import ParamClient
from raspv_common.qos import COMMAND_QOS, EVENT_QOS, GAZE_QOS, LATCHED_QOS
from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown
from raspv_hmd.audio_cues import CueSettings
from raspv_hmd.bridge_frames import BridgeFrames
from raspv_hmd.bridge_params import PARAMS
from raspv_hmd.cue_relay import CueRelay
from raspv_hmd.sender_clock import SenderClock
from raspv_hmd.keymap import key_change, parameters_needed, uses_device_value
from raspv_hmd.server import Callbacks, HeadsetServer, ServerConfig, ServerError
from raspv_spv.device import DeviceError, load_device
from raspv_spv.modes import MODES as SPV_MODES

PARAM_REPLY_TIMEOUT_S = 3.0


def device_values(current: dict[str, Any]) -> dict[str, Any] | None:
    """The spv device preset's values when a needed parameter holds "the device's value"."""
    if not any(uses_device_value(k, v) for k, v in current.items()) or not current.get("device"):
        return None
    return dataclasses.asdict(load_device(current["device"]))


class BridgeNode(BridgeFrames, RaspvNode):
    def __init__(self) -> None:
        super().__init__("bridge", PARAMS)
        p = self.params
        try:
            config = ServerConfig(host=p["host"], port=p["port"], tcp_port=None if p["tcp_port"] < 0 else p["tcp_port"],
                                  token=p["token"], compression=p["compression"], deadman_s=p["deadman_timeout"],
                                  max_clients=p["max_clients"], max_refused=p["max_refused"],
                                  tls_cert=p["tls_cert"], tls_key=p["tls_key"])
        except ValueError as exc:
            raise ConfigurationError(str(exc)) from None
        self.pub_head = self.create_publisher(QuaternionStamped, topics.HEAD_ORIENTATION, COMMAND_QOS)
        self.pub_cmd = self.create_publisher(Twist, topics.CMD_VEL, COMMAND_QOS)
        self.pub_gaze = self.create_publisher(Vector3Stamped, topics.GAZE_DIRECTION, GAZE_QOS)   # every sample kept for recorders
        self.pub_presentation = self.create_publisher(String, topics.HMD_PRESENTATION, EVENT_QOS)
        self.gaze_clocks: dict[int, SenderClock] = {}            # per client: its eye tracker's timing
        self.spv = ParamClient(self, p["spv_node"])
        self.requests: collections.deque[tuple[int, Callable[[int], None], float]] = collections.deque()
        self.requests_lock = threading.Lock()
        self.request_id = 0
        self.current: tuple[int, int, float] | None = None      # (request id, client, started)
        self.request_guard = self.create_guard_condition(self._next_request)
        # requests are checked for time-outs while there are any (an idle timer costs rclpy wake-ups)
        self._request_timer = self.create_timer(0.1, self._check_requests)
        self._setup_frames()
        callbacks = Callbacks(on_head_orientation=self.on_head, on_cmd_vel=self.on_cmd_vel, on_key=self.on_key,
                              on_gaze=self.on_gaze, on_presented=self.on_presented,
                              on_param=self.on_param, on_event=lambda text: self.get_logger().info(text),
                              on_experiment=self.on_experiment, on_clients=self._clients_changed.trigger)
        try:
            self.server = HeadsetServer(config, callbacks).start()
        except (ServerError, ValueError) as exc:
            raise ConfigurationError(str(exc)) from None
        self.pub_response = self.create_publisher(String, topics.EXPERIMENT_RESPONSE, EVENT_QOS)
        self.create_subscription(String, topics.EXPERIMENT_INSTRUCTIONS, self.on_instructions, LATCHED_QOS)
        if p["audio_cues"]:      # navigation guidance and stairs → spatial audio in the clients
            self.cues = CueRelay(self, self.server, CueSettings(enabled=tuple(p["audio_cues"])))
        for page, tcp in self.server.endpoints():
            native = f"; native clients: {tcp}" if tcp else ""
            print(f"headset client: open {page} in a browser{native}", flush=True)
        if self.server.token and not p["token"]:
            print(f"bridge token (generated, listening on {p['host']}): {self.server.token}", flush=True)

    # -- experiments ----------------------------------------------------------------------------
    def on_instructions(self, msg: String) -> None:
        try:
            info = json.loads(msg.data)
        except json.JSONDecodeError:
            self.warn_throttled("instructions", f"ignoring {topics.EXPERIMENT_INSTRUCTIONS}: not JSON")
            return
        if isinstance(info, dict):
            self.server.show_instructions({k: info.get(k) for k in ("id", "title", "text", "waiting")})

    def on_experiment(self, client: int, action: str, instructions_id: str) -> None:
        self.pub_response.publish(String(data=json.dumps({"action": action, "id": instructions_id,
                                                          "by": f"client {client}"})))
        self.get_logger().info(f"client {client}: experiment {action}")

    # -- from the controlling client (server thread) ----------------------------------------------
    def on_head(self, q: tuple[float, float, float, float], _client_time: float | None) -> None:
        x, y, z, w = q
        self.pub_head.publish(QuaternionStamped(header=self.header(BASE_LINK), quaternion=Quaternion(x=x, y=y, z=z, w=w)))

    def on_presented(self, fps: float, refresh_hz: float | None) -> None:
        """``/hmd/presentation``: what the wearer's page composited over its last second (the spv
        node judges its display rate by it, raspv_spv/page_presentation.py)."""
        self.pub_presentation.publish(String(data=json.dumps({"fps": fps, "refresh_hz": refresh_hz})))

    def on_gaze(self, client: int, direction: tuple[float, float, float] | None, client_time: float | None,
                arrival: float) -> None:
        """``/gaze/direction``: the unit gaze in the head frame, (0, 0, 0) for an invalid sample,
        stamped with the client's time mapped onto ours (:mod:`raspv_hmd.sender_clock`)."""
        if client_time is None:
            stamp = arrival
        else:
            clock = self.gaze_clocks.get(client)
            if clock is None:
                if len(self.gaze_clocks) > 64:
                    self.gaze_clocks.clear()
                clock = self.gaze_clocks[client] = SenderClock()
            stamp = clock.map(client_time, arrival)
        header = self.header("head", stamp)
        x, y, z = direction if direction is not None else (0.0, 0.0, 0.0)
        self.pub_gaze.publish(Vector3Stamped(header=header, vector=Vector3(x=x, y=y, z=z)))

    def on_cmd_vel(self, linear: float, angular: float) -> None:
        vmax, wmax = self.params["max_linear"], self.params["max_angular"]
        twist = Twist()
        twist.linear.x = max(-vmax, min(vmax, linear))
        twist.angular.z = max(-wmax, min(wmax, angular))
        self.pub_cmd.publish(twist)

    def on_key(self, client: int, key: str) -> None:
        try:
            needed = parameters_needed(key)
        except KeyError:
            self.server.notify(f"key {key!r} does nothing here", ok=False, client=client)
            return

        def request(rid: int) -> None:
            def apply(current: dict[str, Any]) -> None:
                try:
                    change = key_change(key, current, self.modes(), device_values(current))
                except (ValueError, DeviceError) as exc:
                    self._finish(rid, str(exc), ok=False)
                    return
                self._set(rid, change.name, change.value, current.get(change.name), change.text)
            self._get(rid, needed, apply)
        self._queue(client, request)

    def on_param(self, client: int, name: str, value: Any) -> None:
        def request(rid: int) -> None:
            def apply(current: dict[str, Any]) -> None:
                if current[name] is None:
                    self._finish(rid, f"{self.spv.target} has no parameter {name!r}", ok=False)
                else:
                    self._set(rid, name, value, current[name], f"{name} → {value}")
            self._get(rid, [name], apply)
        self._queue(client, request)

    def modes(self) -> list[str]:
        return list(self.params["modes"]) or list(SPV_MODES)

    # -- spv parameter requests, one at a time (executor thread) -----------------------------------
    def _queue(self, client: int, request: Callable[[int], None]) -> None:
        with self.requests_lock:
            self.requests.append((client, request, time.monotonic()))
        self.request_guard.trigger()

    def _spv_ready(self) -> bool:
        return self.spv.is_ready()

    def _next_request(self) -> None:
        """Start the oldest queued request once the previous one ended and the spv node's
        parameter services are discovered (requests wait up to PARAM_REPLY_TIMEOUT_S for that)."""
        if self._request_timer.is_canceled():
            self._request_timer.reset()
        with self.requests_lock:
            if self.current is not None or not self.requests:
                return
            client, request, queued = self.requests[0]
            ready = self._spv_ready()
            if not ready and time.monotonic() - queued < PARAM_REPLY_TIMEOUT_S:
                return                              # the 0.1 s timer tries again
            self.requests.popleft()
            self.request_id += 1
            self.current = (self.request_id, client, time.monotonic())
            rid = self.request_id
        if ready:
            try:
                request(rid)
            except Exception as exc:  # noqa: BLE001 - one bad request must not stop the bridge
                self._finish(rid, f"request failed: {exc}", ok=False)
        else:
            self._finish(rid, f"node {self.spv.target} is not running or not reachable", ok=False)

    def _get(self, rid: int, names: list[str], then: Callable[[dict[str, Any]], None]) -> None:
        """Current values of ``names`` (None for parameters the node lacks). No answer (the
        node is absent) is reported by the timeout check."""
        self.spv.get_async(names, then)

    def _set(self, rid: int, name: str, value: Any, current: Any, text: str) -> None:
        if isinstance(current, float) and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)

        def done(results: list[tuple[str, bool, str]]) -> None:
            _, ok, reason = results[0]
            self._finish(rid, f"spv {text}" if ok else f"spv refused {name} = {value!r}: {reason}", ok)
        self.spv.set_async({name: value}, done)

    def _finish(self, rid: int, text: str, ok: bool) -> None:
        """End request ``rid`` (late answers to a request that timed out are dropped)."""
        with self.requests_lock:
            if self.current is None or self.current[0] != rid:
                return
            client = self.current[1]
            self.current = None
        self.server.notify(text, ok=ok, client=client)
        if ok:      # (rclpy refuses two severities from one call site)
            self.get_logger().info(f"client {client}: {text}")
        else:
            self.get_logger().warning(f"client {client}: {text}")
        self.request_guard.trigger()

    def _check_requests(self) -> None:
        with self.requests_lock:
            current, waiting = self.current, bool(self.requests)
        if current is not None and time.monotonic() - current[2] > PARAM_REPLY_TIMEOUT_S:
            self._finish(current[0], f"node {self.spv.target} did not answer (is it running?)", ok=False)
        elif current is None and waiting:
            self._next_request()
        elif current is None:
            self._request_timer.cancel()            # idle until the next request (_next_request resets it)

    # -- lifecycle --------------------------------------------------------------------------------
    def close(self) -> None:
        server = getattr(self, "server", None)
        if server is not None:
            try:
                if self.pub_cmd is not None:
                    self.pub_cmd.publish(Twist())        # leave the avatar standing
            except SHUTDOWN_ERRORS as exc:              # the context may already be shut down
                if not during_shutdown(exc, self.context):
                    raise
            stats = server.stats()
            server.stop()
            self._close_frames()
            print(f"bridge: {self.frames} frames and {self.images} images in, {stats.connections} clients served, "
                  f"{stats.refused_total} messages refused, {sum(stats.rejected.values())} connections rejected",
                  flush=True)


def main(argv: list[str] | None = None) -> None:
    run_node(BridgeNode, argv, priority="headset")


if __name__ == "__main__":
    main()
