"""Whether the node behind a topic lives, and what its source is doing (ROS side).

Gaps in data cannot tell a dead node from a slow one; the middleware can. Every RASPV node
(:class:`~raspv_common.node.RaspvNode`) owns a publisher on ``/raspv/alive/<node name>``
(:func:`alive_topic`) with DDS *automatic liveliness* and a lease of :data:`LEASE_S`: the DDS
participant's own thread asserts it while the process runs, so a node killed (SIGKILL) or
stopped (SIGSTOP) loses it within about a lease, whatever its Python threads do, while a node
that is merely slow keeps it. On the same topic the node publishes, latched, what its source
is doing — :data:`DELIVERING` (the default), :data:`PAUSED` (a known pause: a replay paused by
the user) or :data:`DOWN` (nothing will come: a camera unplugged or a recording that does not
open) — so a consumer tells a stop from a pause at once.

A consumer (:class:`ProducerWatch`, used by the spv node and the bridge) resolves which nodes
publish each of its input topics (``get_publishers_info_by_topic``, every
:data:`REFRESH_S`), watches their alive topics (requesting a lease of :data:`WATCH_LEASE_S`:
measured here, a SIGKILL or SIGSTOP is reported 110–160 ms later, and 30 s beside four CPU hogs
gave no false loss) and reports per input one of the states of :mod:`raspv_spv.staleness`:
``alive`` (a producer lives and delivers), ``paused``, ``gone`` (its producers lost their
lease or announced ``down``) or ``unknown`` (its publishers announce nothing: a foreign driver,
a test probe). :mod:`raspv_spv.staleness` turns these into bounds.
"""
from __future__ import annotations

from typing import Callable

from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

ALIVE_PREFIX = "/raspv/alive"
LEASE_S = 0.2          # a node's process asserts its liveliness within this [s] (DDS automatic liveliness)
WATCH_LEASE_S = 0.25   # a consumer requests this (≥ the lease); a dead producer is reported ≈ this late [s]
REFRESH_S = 0.5        # how often a consumer looks up which nodes publish its inputs [s]
DELIVERING, PAUSED, DOWN = "delivering", "paused", "down"
# producer states per input (the same strings as raspv_spv.staleness: ALIVE, PAUSED, GONE, UNKNOWN)
ALIVE, GONE, UNKNOWN = "alive", "gone", "unknown"


def alive_topic(node_fqn: str) -> str:
    """``/raspv/alive/camera`` for the node ``/camera`` (``/raspv/alive/ns/camera`` in a namespace)."""
    return ALIVE_PREFIX + (node_fqn if node_fqn.startswith("/") else "/" + node_fqn)


def _qos(lease_s: float) -> QoSProfile:
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL, liveliness=LivelinessPolicy.AUTOMATIC,
                      liveliness_lease_duration=Duration(seconds=lease_s))


class AliveAnnouncement:
    """A node's ``/raspv/alive/<name>`` publisher: its liveliness, and its source's state."""

    def __init__(self, node: Node) -> None:
        self._pub = node.create_publisher(String, alive_topic(node.get_fully_qualified_name()), _qos(LEASE_S))
        self.state = ""
        self.set(DELIVERING)

    def set(self, state: str) -> None:
        """Announce ``state`` (:data:`DELIVERING`, :data:`PAUSED` or :data:`DOWN`) when it changes."""
        if state not in (DELIVERING, PAUSED, DOWN):
            raise ValueError(f"a source's state is delivering, paused or down, got {state!r}")
        if state != self.state:
            self.state = state
            self._pub.publish(String(data=state))


class _Producer:
    """What a consumer knows of one producing node: its alive writers and its announced state."""

    __slots__ = ("alive", "ever_alive", "state", "sub")

    def __init__(self) -> None:
        self.alive = 0
        self.ever_alive = False
        self.state = DELIVERING
        self.sub = None

    @property
    def verdict(self) -> str:
        if self.alive > 0:
            return {PAUSED: PAUSED, DOWN: GONE}.get(self.state, ALIVE)
        return GONE if self.ever_alive else UNKNOWN


class ProducerWatch:
    """Per input topic, the state of the nodes publishing it (see the module docstring).

    ``watch({input name: topic})`` sets the inputs; :meth:`states` (any thread) returns
    {input name: state}. ``on_change`` (executor thread) is called when a producer's state
    changes, so a display can react before its next check.
    """

    def __init__(self, node: Node, on_change: Callable[[], None] | None = None) -> None:
        self.node = node
        self.on_change = on_change or (lambda: None)
        self._topics: dict[str, str] = {}
        self._publishers: dict[str, frozenset[str]] = {}       # topic → producing node names
        self._producers: dict[str, _Producer] = {}             # node name → what is known of it
        self._states: dict[str, str] = {}
        self._own = node.get_fully_qualified_name()
        node.create_timer(REFRESH_S, self.refresh)

    def watch(self, inputs: dict[str, str]) -> None:
        """Watch the producers of these {input name: topic} (others are forgotten)."""
        self._topics = dict(inputs)
        self.refresh()

    def states(self) -> dict[str, str]:
        """{input name: alive | paused | gone | unknown} (a dict not changed after it is returned)."""
        return self._states

    def refresh(self) -> None:
        """Look up who publishes each watched topic and watch the alive topics of new producers."""
        changed = False
        for topic in set(self._topics.values()):
            try:
                infos = self.node.get_publishers_info_by_topic(topic)
            except Exception:  # noqa: BLE001 - the context is shutting down
                return
            names = frozenset(_fqn(i.node_namespace, i.node_name) for i in infos) - {self._own}
            if names != self._publishers.get(topic):
                self._publishers[topic] = names
                changed = True
            for name in names:
                if name not in self._producers:
                    self._producers[name] = self._subscribe(name)
        if changed:
            self._update()

    def _subscribe(self, name: str) -> _Producer:
        p = _Producer()

        def on_liveliness(info) -> None:
            p.alive = info.alive_count
            p.ever_alive = p.ever_alive or info.alive_count > 0
            self._update()

        def on_state(msg: String) -> None:
            p.state = msg.data
            self._update()

        p.sub = self.node.create_subscription(String, alive_topic(name), on_state, _qos(WATCH_LEASE_S),
                                              event_callbacks=SubscriptionEventCallbacks(liveliness=on_liveliness))
        return p

    def _update(self) -> None:
        states = {}
        for input_name, topic in self._topics.items():
            verdicts = {self._producers[n].verdict for n in self._publishers.get(topic, ()) if n in self._producers}
            states[input_name] = next((v for v in (ALIVE, PAUSED, GONE) if v in verdicts), UNKNOWN)
        if states != self._states:
            self._states = states
            self.on_change()


def _fqn(namespace: str, name: str) -> str:
    return (namespace.rstrip("/") + "/" + name) if namespace not in ("", "/") else "/" + name
