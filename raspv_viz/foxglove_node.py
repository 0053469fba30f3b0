"""The `foxglove` node: the graph's topics and parameters for the Foxglove app.

Every topic of the graph whose message type is installed becomes a channel (ROS 2 CDR with a
``ros2msg`` schema, :mod:`raspv_viz.foxglove_server`), looked up every ``discovery_period``. A
topic is subscribed — raw, so its bytes go out without being deserialised, on a thread of its own
(:mod:`raspv_viz.raw_forwarder`) — only while some
Foxglove client subscribes to its channel; heavy topics nobody watches cost nothing. Derived
channel ``/raspv/latency`` (JSON): per phosphene frame, camera frame → display and the age of the
scene result it used, from /spv/frame. Parameters of every node appear as ``/<node>.<name>``
(e.g. ``/spv.mode``); setting one in Foxglove's parameter panel goes through the node's own
parameter service (refusals are shown as a status message with their reason).

Off the headset path: normal scheduling; the SDK's server runs in its own threads.
"""
from __future__ import annotations

import json
import threading
import time
from functools import partial
from typing import Any

import rclpy
from rcl_interfaces.msg import ParameterType
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from raspv_bags.message_types import typestore
from raspv_common import topics
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.param_client import ParamClient
from raspv_common.qos import TF_QOS, TF_STATIC_LISTENER_QOS
from raspv_common.ros_introspection import message_class
from raspv_viz.foxglove_params import PARAMS
from raspv_viz.foxglove_server import FoxgloveServer, ServerConfig, ros2msg_schema
from raspv_viz.raw_forwarder import RawForwarder

LATENCY = "/raspv/latency"
LATENCY_SCHEMA = json.dumps({
    "title": "raspv.Latency", "type": "object",
    "properties": {"camera_to_display_ms": {"type": "number", "description": "display stamp - camera frame stamp"},
                   "scene_age_ms": {"type": "number", "description": "camera frame stamp - stamp of the scene result used"},
                   "mode": {"type": "string"}}}).encode()
PARAM_TIMEOUT_S = 2.0
_PYTHON_TYPES = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
                 float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING}
TF_TOPICS = frozenset({topics.TF, topics.TF_STATIC})


def installed_class(msgtype: str):
    """``pkg/msg/Name`` → its Python class, None when the package is not installed."""
    try:
        return message_class(msgtype)
    except ValueError:
        return None


def latency_sample(raw: bytes) -> dict[str, Any]:
    """``/raspv/latency`` of one raw ``/spv/frame``: decoded by rosbags (0.1 ms here; rclpy's
    deserialize_message takes 1.1 ms for the 1000-phosphene arrays)."""
    frame = typestore().deserialize_cdr(raw, "raspv_msgs/msg/PhospheneFrame")
    source = frame.source_stamp.sec + frame.source_stamp.nanosec * 1e-9
    display = frame.header.stamp.sec + frame.header.stamp.nanosec * 1e-9
    sample: dict[str, Any] = {"camera_to_display_ms": 1000.0 * (display - source), "mode": frame.mode}
    scene = frame.scene_stamp.sec + frame.scene_stamp.nanosec * 1e-9
    if scene > 0:
        sample["scene_age_ms"] = 1000.0 * (source - scene)
    return sample


def split_parameter(name: str) -> tuple[str, str]:
    """``/spv.mode`` (or ``spv.mode``) → (``/spv``, ``mode``): node names contain no dot."""
    node, _, param = name.partition(".")
    return (node if node.startswith("/") else "/" + node), param


class FoxgloveNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("foxglove", PARAMS)
        self._wake = self.create_guard_condition(self._update_subscriptions)
        self._started = time.monotonic()
        self._forwarded: dict[str, list[int]] = {}   # channel → [messages, bytes] sent to clients
        self._taken: dict[str, tuple[str, QoSProfile]] = {}     # ROS topic forwarded → (its type, QoS)
        # the forwarded topics are taken on a thread of their own (raspv_viz.raw_forwarder)
        self.forwarder = RawForwarder(self.context, f"{self.get_name()}_forward")
        self._channel_types: dict[str, str] = {}     # channel topic → message type
        self._param_clients: dict[str, ParamClient] = {}
        self._last_sent: dict[str, int] = {}         # topic → time of the last forwarded message [ns]
        p = self.params
        # Parameter clients (4 per node of the graph) live on a node of their own, spun by its own
        # thread: in this node's wait set they made every forwarded message cost more.
        self._param_node = None
        if p["parameters"]:
            # its own name: the launcher's `-r __node:=…` would otherwise rename it to this node's
            self._param_node = rclpy.create_node(f"{self.get_name()}_parameters", context=self.context,
                                                 use_global_arguments=False)
            self._param_executor = SingleThreadedExecutor(context=self.context)
            self._param_executor.add_node(self._param_node)
            threading.Thread(target=self._spin_parameters, name="foxglove-parameters", daemon=True).start()
        self.server = FoxgloveServer(
            ServerConfig(host=p["host"], port=p["port"], token=p["token"], sysinfo_topic="/sysinfo" if p["sysinfo"] else ""),
            on_first_subscriber=self._changed, on_last_unsubscribed=self._changed,
            get_parameters=self.get_graph_parameters if p["parameters"] else None,
            set_parameters=self.set_graph_parameters if p["parameters"] else None)
        try:
            self.server.start()
        except (OSError, RuntimeError) as exc:
            raise ConfigurationError(f"cannot serve on {p['host']}:{p['port']}: {exc}") from None
        self.server.add_channel(LATENCY, "raspv.Latency", LATENCY_SCHEMA, "jsonschema", "json")
        self.get_logger().info(f"Foxglove: open connection → Foxglove WebSocket → {self.server.url()}")
        self.discover()
        self.create_timer(p["discovery_period"], self.discover)

    def close(self) -> None:
        self.forwarder.close()
        self.server.stop()
        wall = time.monotonic() - self._started
        messages = sum(n for n, _ in self._forwarded.values())
        megabytes = sum(b for _, b in self._forwarded.values()) / 1e6
        print(f"foxglove: {messages} messages ({megabytes:.0f} MB) sent on {len(self._forwarded)} channels in "
              f"{wall:.0f} s, CPU {time.process_time():.1f} s", flush=True)
        if self._param_node is not None:
            self._param_executor.shutdown(timeout_sec=1.0)
            self._param_node.destroy_node()

    def _spin_parameters(self) -> None:
        try:
            self._param_executor.spin()
        except (ExternalShutdownException, RuntimeError):   # the context shut down with the process
            pass

    # -- channels ----------------------------------------------------------------------------
    def discover(self) -> None:
        """Channels for the graph's topics now (new ones added, vanished ones removed)."""
        wanted, exclude = set(self.params["topics"]), set(self.params["exclude"])
        present: dict[str, str] = {}
        for topic, types in self.get_topic_names_and_types():
            if len(types) == 1 and topic not in exclude and (not wanted or topic in wanted):
                present[topic] = types[0]
        for topic, msgtype in present.items():
            if self._channel_types.get(topic) == msgtype:
                continue
            schema = ros2msg_schema(msgtype)
            if schema is None or installed_class(msgtype) is None:
                self.warn_throttled(f"type-{msgtype}", f"{topic}: type {msgtype} not installed here; not served", 60.0)
                continue
            if topic in self._channel_types:
                self.server.remove_channel(topic)
            self.server.add_channel(topic, msgtype, schema)
            self._channel_types[topic] = msgtype
        for topic in [t for t in self._channel_types if t not in present]:
            del self._channel_types[topic]
            self.server.remove_channel(topic)
        self._update_subscriptions()

    def _changed(self, _topic: str) -> None:
        """A channel got its first or lost its last client (SDK thread): wake the executor."""
        self._wake.trigger()

    def _needed(self) -> set[str]:
        needed = {t for t in self._channel_types if self.server.watched(t)}
        if self.server.watched(LATENCY) and topics.SPV_FRAME in self._channel_types:
            needed.add(topics.SPV_FRAME)
        return needed

    def _update_subscriptions(self) -> None:
        needed = {t: self._channel_types[t] for t in self._needed()}
        if needed == {t: msgtype for t, (msgtype, _) in self._taken.items()}:
            return
        self._taken = {t: self._taken[t] if self._taken.get(t, ("",))[0] == msgtype else (msgtype, self._qos_for(t))
                       for t, msgtype in needed.items()}
        self.forwarder.set_topics({t: (installed_class(msgtype), qos, partial(self._forward, t))
                                   for t, (msgtype, qos) in self._taken.items()})

    def _qos_for(self, topic: str) -> QoSProfile:
        """Keep-last 2, reliable and transient-local when every publisher is (latched topics reach
        a late Foxglove client), best-effort when any publisher is; tf as a tf listener takes it
        (every node's latched /tf_static message, no /tf sample lost)."""
        if topic == topics.TF_STATIC:
            return TF_STATIC_LISTENER_QOS
        if topic == topics.TF:
            return TF_QOS
        infos = self.get_publishers_info_by_topic(topic)
        latched = bool(infos) and all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
        reliable = all(i.qos_profile.reliability != ReliabilityPolicy.BEST_EFFORT for i in infos)
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1 if latched else 2,
                          reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)

    def _forward(self, topic: str, raw: bytes) -> None:
        now = time.time_ns()
        max_rate = self.params["max_rate"]
        if max_rate > 0 and topic not in TF_TOPICS:     # thin fast topics for viewers (not tf: every edge counts)
            if now - self._last_sent.get(topic, 0) < 1e9 / max_rate:
                return
            self._last_sent[topic] = now
        if self.server.watched(topic):
            self._send(topic, raw, now)
        if topic == topics.SPV_FRAME and self.server.watched(LATENCY):
            self._send(LATENCY, json.dumps(latency_sample(raw)).encode(), now)

    def _send(self, channel: str, data: bytes, now: int) -> None:
        self.server.log(channel, data, now)
        counts = self._forwarded.setdefault(channel, [0, 0])
        counts[0] += 1
        counts[1] += len(data)

    # -- parameters (called on the SDK's thread; the executor answers the services) ----------
    def _client(self, node: str) -> ParamClient:
        if node not in self._param_clients:
            self._param_clients[node] = ParamClient(self._param_node, node)
        return self._param_clients[node]

    def _graph_nodes(self) -> list[str]:
        mine = {self.get_fully_qualified_name(), self._param_node.get_fully_qualified_name()}
        names = [(ns.rstrip("/") + "/" + n) for n, ns in self.get_node_names_and_namespaces()]
        return sorted({n for n in names if n not in mine and not n.rsplit("/", 1)[-1].startswith("_")})

    def _ask(self, client: ParamClient, ask) -> Any:
        ok, answer = client.ask_until_answered(ask, PARAM_TIMEOUT_S, retry_s=1.0)
        return answer if ok else None

    def get_graph_parameters(self, names: list[str]) -> list[tuple[str, Any]]:
        """(``/node.param``, value) of the names asked for, or of every node's parameters."""
        wanted: dict[str, list[str] | None] = {}
        if names:
            for name in names:
                node, param = split_parameter(name)
                wanted.setdefault(node, []).append(param)
        else:
            wanted = {node: None for node in self._graph_nodes()}
        out: list[tuple[str, Any]] = []
        for node, params in wanted.items():
            client = self._client(node)
            if params is None:
                params = self._ask(client, client.list_async) or []
            if not params:
                continue
            values = self._ask(client, lambda done, ps=params: client.get_async(ps, done)) or {}
            out += [(f"{node}.{k}", v) for k, v in values.items() if v is not None]
        return out

    def set_graph_parameters(self, values: dict[str, Any]) -> list[tuple[str, Any]]:
        """Set each ``/node.param``; returns the values they have afterwards (a refused change keeps
        the old value, and its reason goes to the clients as a status message)."""
        by_node: dict[str, dict[str, Any]] = {}
        for name, value in values.items():
            node, param = split_parameter(name)
            by_node.setdefault(node, {})[param] = value
        out: list[tuple[str, Any]] = []
        for node, changes in by_node.items():
            client = self._client(node)
            current = self._ask(client, lambda done, ps=list(changes): client.get_async(ps, done)) or {}
            types = {k: _PYTHON_TYPES.get(type(v)) for k, v in current.items() if v is not None}
            types.update({k: ParameterType.PARAMETER_DOUBLE_ARRAY for k, v in current.items()
                          if isinstance(v, list) and v and all(isinstance(x, float) for x in v)})
            results = self._ask(client, lambda done: client.set_async(changes, done, types)) or \
                [(k, False, f"{node} did not answer") for k in changes]
            for param, ok, reason in results:
                if not ok:
                    self.server.status(f"{node}.{param}: {reason}")
                    self.get_logger().warning(f"Foxglove set {node}.{param} refused: {reason}")
            after = self._ask(client, lambda done, ps=list(changes): client.get_async(ps, done)) or current
            out += [(f"{node}.{k}", v) for k, v in after.items() if v is not None]
        return out


def main(argv=None) -> None:
    run_node(FoxgloveNode, argv, priority="perception")


if __name__ == "__main__":
    main()
