"""The Foxglove WebSocket server of the `foxglove` node, on foxglove-sdk (no rclpy).

Channels carry ROS 2 messages as the Foxglove app reads them from a ROS 2 graph: message
encoding ``cdr`` (the bytes the topic carries, encapsulation header included) and schema
encoding ``ros2msg`` (the type's .msg text followed by each dependency's, ``MSG: pkg/Type``
blocks; :func:`ros2msg_schema`). The owner learns when the first client subscribes to a channel
and when the last one leaves (``on_first_subscriber`` / ``on_last_unsubscribed``), so it only
takes the topics somebody watches; parameters are fetched and set through the owner's
``get_parameters`` / ``set_parameters``, called on the SDK's thread.

Security: bound to loopback by default. Bound anywhere else it requires a token: the SDK server
then listens on an ephemeral loopback port behind :class:`raspv_viz.foxglove_gate.TokenGate`,
which admits only WebSocket requests carrying ``?token=…`` (as the headset bridge does).
"""
from __future__ import annotations

import logging
import secrets
import threading
from dataclasses import dataclass
from typing import Any, Callable

from raspv_bags.message_types import ensure_type, normalise_type, typestore
from raspv_common.extras import require

# the `foxglove` extra; without it, importing this module raises MissingExtra (one line: its install)
foxglove = require("foxglove", "the foxglove node (the graph live in the Foxglove app)")
from foxglove import Capability, Parameter, ParameterType, Schema  # noqa: E402
from raspv_viz.foxglove_gate import TokenGate, is_loopback

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")   # the SDK speaks the first; the gate relays either
STOP_WAIT_S = 2.0    # s: the SDK's stop waits for every client's queue to drain; a client that stopped reading
                     # (a laptop gone to sleep) made it wait for that client's TCP to fail (46 s here)


HANDSHAKE_HINT = ("the SDK accepts only clients offering the WebSocket subprotocol foxglove.sdk.v1: an older "
                  "Foxglove app offering only foxglove.websocket.v1 gets HTTP 400, as does a request that is not "
                  "a WebSocket upgrade")


class _HandshakeReason(logging.Filter):
    """foxglove-sdk logs a refused handshake as "Dropping client ADDR: handshake failed" (the
    client gets HTTP 400 "Missing expected sec-websocket-protocol header"): add why, so the node's
    log says it."""

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        if message.endswith("handshake failed"):
            record.msg, record.args = f"{message} ({HANDSHAKE_HINT})", ()
        return True


_SDK_SERVER_LOG = logging.getLogger("foxglove.websocket.server")
if not any(isinstance(f, _HandshakeReason) for f in _SDK_SERVER_LOG.filters):
    _SDK_SERVER_LOG.addFilter(_HandshakeReason())


def ros2msg_schema(msgtype: str) -> bytes | None:
    """The ``ros2msg`` schema text of a ROS 2 type (``pkg/msg/Name``), None if unknown."""
    name = normalise_type(msgtype)
    if not ensure_type(name):
        return None
    text, _ = typestore().generate_msgdef(name, ros_version=2)
    return text.encode()


def to_foxglove_parameter(name: str, value: Any) -> Parameter:
    """A ROS parameter value as a Foxglove parameter (floats keep their type on the wire)."""
    if isinstance(value, float):
        return Parameter(name, value=value, type=ParameterType.Float64)
    if isinstance(value, list) and value and all(isinstance(v, float) for v in value):
        return Parameter(name, value=value, type=ParameterType.Float64Array)
    return Parameter(name, value=value)


@dataclass
class ServerConfig:
    host: str = "127.0.0.1"
    port: int = 8767              # 0: any free port
    token: str = ""               # required off-loopback; generated when empty
    name: str = "raspv"
    sysinfo_topic: str = "/sysinfo"   # CPU and memory of this process and the machine ("" = none)

    @property
    def loopback(self) -> bool:
        return is_loopback(self.host)


class FoxgloveServer:
    """Channels by topic, subscription counting, parameters; thread-safe."""

    def __init__(self, config: ServerConfig, on_first_subscriber: Callable[[str], None],
                 on_last_unsubscribed: Callable[[str], None],
                 get_parameters: Callable[[list[str]], list[tuple[str, Any]]] | None = None,
                 set_parameters: Callable[[dict[str, Any]], list[tuple[str, Any]]] | None = None) -> None:
        self.config = config
        self.token = "" if config.loopback else (config.token or secrets.token_urlsafe(12))
        self._on_first, self._on_last = on_first_subscriber, on_last_unsubscribed
        self._get, self._set = get_parameters, set_parameters
        self._lock = threading.Lock()
        self._channels: dict[str, foxglove.Channel] = {}
        self._subscribers: dict[str, set[int]] = {}      # topic → client ids
        self._context = foxglove.Context()
        self._server: foxglove.WebSocketServer | None = None
        self._gate: TokenGate | None = None
        self._sysinfo = None
        self.port: int | None = None

    # -- life ----------------------------------------------------------------------------------
    def start(self) -> None:
        capabilities = [Capability.Parameters] if self._get is not None else []
        direct = self.config.loopback
        self._server = foxglove.start_server(
            name=self.config.name, host=self.config.host if direct else "127.0.0.1",
            port=self.config.port if direct else 0, capabilities=capabilities, server_listener=_Listener(self),
            context=self._context)
        if direct:
            self.port = self._server.port
        else:
            self._gate = TokenGate(self.config.host, self.config.port, self.token, self._server.port, SUBPROTOCOLS)
            self.port = self._gate.start()
        if self.config.sysinfo_topic:
            self._sysinfo = foxglove.start_sysinfo_publisher(topic=self.config.sysinfo_topic, refresh_interval=1.0,
                                                             context=self._context)

    def url(self) -> str:
        host = "127.0.0.1" if self.config.host in ("0.0.0.0", "::", "") else self.config.host
        return f"ws://{host}:{self.port}" + (f"/?token={self.token}" if self.token else "")

    def stop(self) -> None:
        """Stop serving; waits at most STOP_WAIT_S for the SDK (the rest finishes, or is dropped
        with the process)."""
        if self._sysinfo is not None:
            self._sysinfo.stop()
        if self._gate is not None:
            self._gate.stop()
        stopper = threading.Thread(target=self._stop_server, name="foxglove-stop", daemon=True)
        stopper.start()
        stopper.join(STOP_WAIT_S)

    def _stop_server(self) -> None:
        if self._server is not None:
            self._server.stop()
        with self._lock:
            channels, self._channels = list(self._channels.values()), {}
        for channel in channels:
            channel.close()

    # -- channels -------------------------------------------------------------------------------
    def topics(self) -> set[str]:
        with self._lock:
            return set(self._channels)

    def add_channel(self, topic: str, schema_name: str, schema: bytes, schema_encoding: str = "ros2msg",
                    message_encoding: str = "cdr") -> None:
        with self._lock:
            if topic not in self._channels:
                self._channels[topic] = foxglove.Channel(
                    topic, schema=Schema(name=schema_name, encoding=schema_encoding, data=schema),
                    message_encoding=message_encoding, context=self._context)

    def remove_channel(self, topic: str) -> None:
        with self._lock:
            channel = self._channels.pop(topic, None)
            watched = bool(self._subscribers.pop(topic, None))
        if channel is not None:
            channel.close()
        if watched:
            self._on_last(topic)

    def log(self, topic: str, data: bytes, log_time_ns: int) -> None:
        channel = self._channels.get(topic)
        if channel is not None:
            channel.log(data, log_time=log_time_ns)

    def watched(self, topic: str) -> bool:
        return self.watchers(topic) > 0

    def watchers(self, topic: str) -> int:
        """How many clients subscribe to the channel of ``topic``."""
        with self._lock:
            return len(self._subscribers.get(topic, ()))

    def status(self, message: str) -> None:
        """A warning every connected client shows (e.g. a refused parameter change and why)."""
        if self._server is not None:
            self._server.publish_status(message, foxglove.StatusLevel.Warning)

    def publish_parameters(self, values: list[tuple[str, Any]]) -> None:
        if self._server is not None and values:
            self._server.publish_parameter_values([to_foxglove_parameter(n, v) for n, v in values])

    # -- listener events (SDK thread) -----------------------------------------------------------
    def _subscribed(self, client_id: int, topic: str) -> None:
        with self._lock:
            clients = self._subscribers.setdefault(topic, set())
            first = not clients
            clients.add(client_id)
        if first:
            self._on_first(topic)

    def _unsubscribed(self, client_id: int, topic: str) -> None:
        with self._lock:
            clients = self._subscribers.get(topic, set())
            had = bool(clients)
            clients.discard(client_id)
            last = had and not clients
        if last:
            self._on_last(topic)


class _Listener:
    """foxglove.websocket.ServerListener for :class:`FoxgloveServer`."""

    def __init__(self, owner: FoxgloveServer) -> None:
        self.owner = owner

    def on_subscribe(self, client, channel) -> None:
        self.owner._subscribed(client.id, channel.topic)

    def on_unsubscribe(self, client, channel) -> None:
        self.owner._unsubscribed(client.id, channel.topic)

    def on_get_parameters(self, client, param_names, request_id=None) -> list[Parameter]:
        if self.owner._get is None:
            return []
        return [to_foxglove_parameter(n, v) for n, v in self.owner._get(list(param_names))]

    def on_set_parameters(self, client, parameters, request_id=None) -> list[Parameter]:
        if self.owner._set is None:
            return []
        values = self.owner._set({p.name: p.get_value() for p in parameters})
        self.owner.publish_parameters(values)
        return [to_foxglove_parameter(n, v) for n, v in values]

    def on_parameters_subscribe(self, param_names) -> None:
        return None

    def on_parameters_unsubscribe(self, param_names) -> None:
        return None
