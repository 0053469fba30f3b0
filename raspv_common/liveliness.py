"""Whether the node behind a topic lives, and what its source is doing (ROS side).

Gaps in data cannot tell a dead node from a slow one. Every RASPV node
(:class:`~raspv_common.node.RaspvNode`) owns a publisher on ``/raspv/alive/<node name>``
(:func:`alive_topic`) on which it publishes, latched, what its source is doing —
:data:`DELIVERING` (the default), :data:`PAUSED` (a known pause: a replay paused by the user) or
:data:`DOWN` (nothing will come: a camera unplugged, a recording that does not open) — and who
it is: its pid, start time and pid namespace (:func:`raspv_common.process_state.identity`).

A consumer (:class:`ProducerWatch`, used by the spv node and the bridge) resolves which nodes
publish each of its input topics (``get_publishers_info_by_topic``, every :data:`REFRESH_S`) and
watches their announcements. Whether a producer lives:

- **on this machine** (same pid namespace): from ``/proc`` (:mod:`raspv_common.process_state`) —
  killed or stopped with SIGSTOP is known at once, and a process starved of CPU stays alive
  however late its threads run. (DDS leases are not used here: on this 2-core machine, loaded
  by the graph and a browser, the scene and odometry nodes' 0.2 s leases lapsed every few
  seconds while they worked.)
- **on another machine**: from DDS *automatic liveliness* of the alive publisher (lease
  :data:`LEASE_S`, requested :data:`WATCH_LEASE_S`; measured here, a SIGKILL or SIGSTOP is
  reported 110–160 ms later).

Per input it reports one of the states of :mod:`raspv_spv.staleness`: ``alive`` (a producer
lives and delivers), ``paused``, ``gone`` (its producers died, are stopped, or announced
``down``) or ``unknown`` (its publishers announce nothing: a foreign driver, a test probe).
A producer whose alive publisher is in the ROS graph but whose announcement has not reached the
consumer yet (a graph starting: the consumer's subscription still matching) counts as ``alive``
unless another producer of the input is known dead (:func:`combined_state`):
it is a RASPV node that started — judging its first frames by the crash detector's 0.26 s bound
showed the no-data ring while a loaded machine started the graph. The first message of an input
whose producers are not known yet triggers the lookup at once (not at the next :data:`REFRESH_S`).
:mod:`raspv_spv.staleness` turns these into bounds.

*The process, not the node name.* A node restarted by the launcher comes back under the same name
— from a warm spare, registered ~0.2 s after the kill, long before its first message. Judged by
name, the input's producer then counted as alive and the 1-s late bound applied instead of the
dead bound (issue 36: a headset without frames for 1.02 s after ``kill -9`` of spv). So an
input's state follows the processes that could have sent its last message — the live local
processes among its producers when it arrived (:meth:`ProducerWatch.arrived`) —: while the
replacement has sent nothing, the input's producer is the dead process. (A message that came
when none of them lived is from a process not heard yet: judged by name until the next one.) (Producers on another
machine are judged by name: DDS liveliness is per topic, not per process.) Endpoints whose node
is not known yet (rmw's ``_NODE_NAME_UNKNOWN_``: a process whose node announcement has not
arrived) are left out until it has.
"""
from __future__ import annotations


import json
import threading
import time

from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from raspv_common import process_state as proc
from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown

ALIVE_PREFIX = "/raspv/alive"
LEASE_S = 0.2          # a node's process asserts its liveliness within this [s] (DDS automatic liveliness)
WATCH_LEASE_S = 0.25   # a consumer requests this (≥ the lease); a dead producer is reported ≈ this late [s]
REFRESH_S = 0.5        # how often a consumer looks up which nodes publish its inputs [s]
STATES_TTL_S = 0.02    # a consumer's verdicts are re-read from /proc at most this often [s]
EAGER_REFRESH_S = 0.1  # an input from producers not known yet: looked up at most this often [s]
DELIVERING, PAUSED, DOWN = "delivering", "paused", "down"
# producer states per input (the same strings as raspv_spv.staleness: ALIVE, PAUSED, GONE, UNKNOWN)
ALIVE, GONE, UNKNOWN = "alive", "gone", "unknown"
PENDING = "pending"    # a producer's verdict only: its alive publisher is in the graph, its announcement not yet here
UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"   # rmw's name of an endpoint whose node announcement has not arrived
MAX_PROCESSES = 8      # processes remembered per node name (a restarted node's old ones, until they are gone)


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
            self._pub.publish(String(data=json.dumps({"state": state, **proc.identity()})))


class _Producer:
    """What a consumer knows of one producing node: its announcement and its DDS liveliness."""

    __slots__ = ("alive", "ever_alive", "announces", "heard", "state", "pid", "started", "local", "sub", "processes")

    def __init__(self) -> None:
        self.alive = 0                 # DDS: alive writers on its alive topic
        self.ever_alive = False
        self.announces = False         # the ROS graph shows its alive publisher (a RASPV node)
        self.heard = False             # its announcement arrived
        self.state = DELIVERING
        self.pid = self.started = 0
        self.local = False             # the same pid namespace: /proc tells whether it lives
        self.sub = None
        self.processes: dict[tuple[int, int], str] = {}   # (pid, started) → announced state, of local processes

    def announced(self, data: str) -> None:
        try:
            info = json.loads(data)
        except ValueError:
            info = {"state": data} if data in (DELIVERING, PAUSED, DOWN) else None   # a bare state word
        if not isinstance(info, dict):
            return                     # garbage: as if nothing was heard
        self.heard = True
        self.state = str(info.get("state", DELIVERING))
        self.pid, self.started = int(info.get("pid") or 0), int(info.get("started") or 0)
        self.local = bool(self.pid) and bool(proc.NAMESPACE) and info.get("ns") == proc.NAMESPACE
        if self.local:
            self.processes[(self.pid, self.started)] = self.state
            if len(self.processes) > MAX_PROCESSES:      # forget processes that are gone (never the newest)
                for key in [k for k in list(self.processes) if k != (self.pid, self.started)
                            and proc.process_state(*k) == proc.GONE][:len(self.processes) - MAX_PROCESSES]:
                    del self.processes[key]

    def process_verdict(self, key: tuple[int, int]) -> str:
        """The verdict on one local process of this node (:attr:`processes`): gone when it died,
        was forgotten, or announced ``down``."""
        state = self.processes.get(key)
        if state is None or proc.process_state(*key) != proc.RUNNING:
            return GONE
        return {PAUSED: PAUSED, DOWN: GONE}.get(state, ALIVE)

    def live_processes(self) -> list[tuple[int, int]]:
        """The local processes of this node that could publish now (not gone). Called from a
        consumer's other threads while its executor adds announcements: iterates a copy (the
        bridge's frames thread died of "dictionary changed size during iteration")."""
        return [k for k in list(self.processes) if self.process_verdict(k) != GONE]

    @property
    def verdict(self) -> str:
        if self.local:
            if proc.process_state(self.pid, self.started) != proc.RUNNING:
                return GONE
            return {PAUSED: PAUSED, DOWN: GONE}.get(self.state, ALIVE)
        if self.alive > 0:
            return {PAUSED: PAUSED, DOWN: GONE}.get(self.state, ALIVE)
        if self.ever_alive:
            return GONE
        return PENDING if self.announces and not self.heard else UNKNOWN   # its announcement is on its way


class ProducerWatch:
    """Per input topic, the state of the nodes publishing it (see the module docstring).

    ``watch({input name: topic})`` sets the inputs; :meth:`states` (any thread) returns
    {input name: state}, re-read from ``/proc`` at most every :data:`STATES_TTL_S`.
    """

    def __init__(self, node: Node) -> None:
        self.node = node
        self._topics: dict[str, str] = {}
        self._publishers: dict[str, frozenset[str]] = {}       # topic → producing node names
        self._producers: dict[str, _Producer] = {}             # node name → what is known of it
        self._states: dict[str, str] = {}
        self._sources: dict[str, frozenset[tuple[str, tuple[int, int]]]] = {}   # input → processes of its last message
        self._live: dict[str, frozenset[tuple[str, tuple[int, int]]]] = {}      # topic → its live local processes
        self._states_at = -1.0
        self._refreshed_at = -1.0
        self._refresh_lock = threading.Lock()            # the timer and input callbacks may refresh at once
        self._own = node.get_fully_qualified_name()
        node.create_timer(REFRESH_S, self.refresh)

    def watch(self, inputs: dict[str, str]) -> None:
        """Watch the producers of these {input name: topic} (others are forgotten)."""
        self._sources = {k: v for k, v in self._sources.items() if self._topics.get(k) == inputs.get(k)}
        self._topics = dict(inputs)
        self.refresh()

    def states(self) -> dict[str, str]:
        """{input name: alive | paused | gone | unknown} (a dict not changed after it is returned)."""
        now = time.monotonic()
        if now - self._states_at >= STATES_TTL_S:
            self._update()
            self._states_at = now
        return self._states

    def arrived(self, input_name: str) -> None:
        """A message of ``input_name`` came: it came from one of its producers' live processes
        (their verdicts ≤ :data:`STATES_TTL_S` old), whose fate the input's state follows from now
        on. While its producers are not known, look them up now (at most every
        :data:`EAGER_REFRESH_S`) rather than at the next periodic refresh."""
        state = self.states().get(input_name, UNKNOWN)
        live = self._live.get(self._topics.get(input_name, ""), frozenset())
        if self._sources.get(input_name) != live:     # none live: a process not heard yet sent it (by name)
            self._sources[input_name] = live
            self._states_at = -1.0
        if state == UNKNOWN and time.monotonic() - self._refreshed_at >= EAGER_REFRESH_S:
            self.refresh()
            self._states_at = -1.0

    def refresh(self) -> None:
        """Look up who publishes each watched topic and watch the alive topics of new producers."""
        with self._refresh_lock:
            self._refreshed_at = time.monotonic()
            for topic in set(self._topics.values()):
                try:
                    infos = self.node.get_publishers_info_by_topic(topic)
                except SHUTDOWN_ERRORS as exc:
                    if during_shutdown(exc, self.node.context):
                        return
                    raise
                names = frozenset(_fqn(i.node_namespace, i.node_name) for i in infos
                                  if i.node_name != UNKNOWN_NODE) - {self._own}
                self._publishers[topic] = names
                for name in names:
                    p = self._producers.get(name)
                    if p is None:
                        p = self._producers[name] = self._subscribe(name)
                    if not p.heard:             # until it is heard: is its alive publisher (still) there?
                        try:
                            p.announces = bool(self.node.get_publishers_info_by_topic(alive_topic(name)))
                        except SHUTDOWN_ERRORS as exc:
                            if during_shutdown(exc, self.node.context):
                                return
                            raise

    def _subscribe(self, name: str) -> _Producer:
        p = _Producer()

        def on_liveliness(info) -> None:
            p.alive = info.alive_count
            p.ever_alive = p.ever_alive or info.alive_count > 0

        p.sub = self.node.create_subscription(String, alive_topic(name), lambda m: p.announced(m.data),
                                              _qos(WATCH_LEASE_S),
                                              event_callbacks=SubscriptionEventCallbacks(liveliness=on_liveliness))
        return p

    def _update(self) -> None:
        states = {}
        self._live = {topic: live_processes(self._producers, self._publishers.get(topic, ()))
                      for topic in set(self._topics.values())}
        for input_name, topic in list(self._topics.items()):
            states[input_name] = input_state(self._producers, self._publishers.get(topic, ()),
                                             self._sources.get(input_name))
        if states != self._states:
            self._states = states


def live_processes(producers: dict[str, _Producer], names) -> frozenset[tuple[str, tuple[int, int]]]:
    """(node name, (pid, started)) of the live local processes of the nodes ``names``: those a
    message arriving now can have come from."""
    return frozenset((n, k) for n in names if (p := producers.get(n)) is not None for k in p.live_processes())


def input_state(producers: dict[str, _Producer], names, sources=None) -> str:
    """An input's state from its producing nodes ``names``; with ``sources`` (the live local
    processes when its last message arrived, :func:`live_processes`) local producers are judged
    by those processes, not by whichever process now holds the node name."""
    known = [p for n in names if (p := producers.get(n)) is not None]
    if not sources:
        return combined_state({p.verdict for p in known})
    verdicts = {producers[n].process_verdict(k) if n in producers else GONE for n, k in sources}
    return combined_state(verdicts | {p.verdict for p in known if not p.local})


def combined_state(verdicts: set[str]) -> str:
    """An input's state from its producers' verdicts: alive, paused, gone, then a producer whose
    announcement is still on its way (alive: a graph starting), else unknown. A dead producer
    outranks a pending one, so a camera killed while its replacement starts is shown at once."""
    state = next((v for v in (ALIVE, PAUSED, GONE) if v in verdicts), None)
    if state is not None:
        return state
    return ALIVE if PENDING in verdicts else UNKNOWN


def _fqn(namespace: str, name: str) -> str:
    return (namespace.rstrip("/") + "/" + name) if namespace not in ("", "/") else "/" + name
