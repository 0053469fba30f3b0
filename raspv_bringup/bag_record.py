"""`raspv bag record`: the graph's topics into a bag, behind the graph (see :func:`record`).

Raw subscriptions (bytes written unchanged) with QoS matched to the publishers, topics that
appear later picked up, live counts on one status line; Ctrl-C or SIGTERM closes a complete bag;
a SIGKILLed recording stays readable (``raspv bag repair`` makes it complete for other tools).
The recorder runs in a session of its own (:mod:`raspv_bringup.own_session`), lowered to
:data:`RECORDER_NICE` (``--nice``) once its subscriptions are made and its bag is open; its
subscriptions hold :data:`RECORD_DEPTH` messages each while it is behind, and messages lost all
the same are counted from the publishers' sequence numbers (:mod:`raspv_bags.sequence_gaps`) and
reported on the status line and in the summary.
"""
from __future__ import annotations

import argparse
import datetime as dt
import os
import signal
import sys
import time
from pathlib import Path

from raspv_bringup.middleware import apply_middleware_defaults
from raspv_bringup.own_session import run_in_own_session
from raspv_common.thread_priority import lower_process_priority

# Level with the cameras (nice 2; perception 5; each node a session of its own), never ahead of
# them. Lower lost messages on this shared 2-core machine without a camera rate measurably
# higher: session nice 5 lost 0-21 %, nice 10 10-91 % at load 6-16; nice 0 and 2 none (docs/bags.md).
# Each subscription keeps this many messages while the recorder waits (~20 s of a 15 Hz camera;
# 0.5-1 MB per camera image).
RECORDER_NICE = 2
RECORD_DEPTH = 300
CLEAR_EOL = "\x1b[K"  # erase the rest of a terminal line


def err(action: str, text: str) -> int:
    print(f"raspv bag {action}: {text}", file=sys.stderr)
    return 1


def record(args: argparse.Namespace) -> int:
    """Capture first, write second: the subscriptions to the known topics are made before the
    bag is opened and rosbags' message types are loaded (≈0.4 s of CPU, issue 27), and the
    messages that arrive meanwhile wait in each subscription's history (RECORD_DEPTH deep) and enter
    the bag with the time the middleware received them."""
    from raspv_bags.recording import TopicSelection
    from raspv_common.startup_timing import startup_mark
    startup_mark("command started")

    if args.duration is not None and args.duration <= 0:
        return err("record", f"--duration must be > 0, got {args.duration}")
    if args.flush_interval <= 0:
        return err("record", f"--flush-interval must be > 0, got {args.flush_interval}")
    out = Path(args.output or dt.datetime.now().strftime("rosbag2_%Y_%m_%d-%H_%M_%S"))
    if out.exists():                     # BagWriter says so too; here before any ROS start-up
        return err("record", f"{out} exists already; choose a new output directory")
    if not out.absolute().parent.is_dir():
        return err("record", f"{out.absolute().parent} is not a directory")
    if args.storage != "mcap" and args.compression not in (None, "none"):
        return err("record", f"--compression {args.compression} is for MCAP bags (their chunks); "
                              f"{args.storage} bags are written uncompressed")
    selection = TopicSelection(tuple(args.topics), tuple(args.exclude), images=args.images)
    # a session of its own (own_session.py), lowered to `nice` once recording; the subscriptions'
    # histories (RECORD_DEPTH) hold what arrives while it waits, and what they lose is counted
    nice = RECORDER_NICE if args.nice is None else args.nice
    if not 0 <= nice <= 19:
        return err("record", f"--nice must be 0-19, got {nice}")
    return run_in_own_session(lambda: _record_graph(args, out, selection, nice))


def _record_graph(args: argparse.Namespace, out: Path, selection, nice: int) -> int:
    from raspv_common.startup_timing import startup_mark
    apply_middleware_defaults()
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    stop = []
    previous = {s: signal.signal(s, lambda *_: stop.append(True)) for s in (signal.SIGINT, signal.SIGTERM)}
    rclpy.init(args=["raspv", "--ros-args", "--disable-rosout-logs"], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(f"raspv_bag_record_{os.getpid()}")
    startup_mark("node created")
    tty = sys.stderr.isatty()
    recorder = _GraphRecorder(node, selection, tty)
    recorder.subscribe_known()          # before discovery: the first message of every known topic
    startup_mark("known topics subscribed")
    recording = None
    try:
        recording = recorder.open_bag(out, args.storage, args.flush_interval, args.compression)
        startup_mark("bag opened")
        lower_process_priority(nice)    # subscribed and open at full speed: from here on behind the graph
        how = args.storage + (f", {recording.writer.compression} chunks" if recording.writer.compression != "none" else "")
        print(f"recording to {out} ({how}); Ctrl-C to stop", file=sys.stderr, flush=True)
        start = time.monotonic()
        last_status = last_discovery = last_flush = 0.0
        while not stop and rclpy.ok():
            rclpy.spin_once(node, timeout_sec=0.05)
            now = time.monotonic()
            if now - last_discovery >= 0.5:
                last_discovery = now
                recorder.discover()
            if now - last_flush >= args.flush_interval:
                last_flush = now
                recording.flush()
            if tty and now - last_status >= 0.5 or not tty and now - last_status >= 5.0:
                last_status = now
                width = os.get_terminal_size(sys.stderr.fileno()).columns - 1 if tty else 200
                line = recording.status_line(width)
                print(f"\r{line}{CLEAR_EOL}" if tty else line, end="" if tty else "\n", file=sys.stderr, flush=True)
            if args.duration is not None and now - start >= args.duration:
                break
    except _BagOpenError as exc:
        return err("record", str(exc))
    finally:
        if recording is not None:
            recording.close()
        node.destroy_node()
        rclpy.try_shutdown()
        for s, h in previous.items():
            signal.signal(s, h)
    if tty:
        print(file=sys.stderr)
    for pattern in selection.unmatched(recording.topics):
        print(f"raspv bag record: no topic matching {pattern} appeared", file=sys.stderr)
    print(recording.summary())
    return 0


class _BagOpenError(Exception):
    """The bag could not be created (one line)."""


class _GraphRecorder:
    """Subscribes (raw) to the selected known topics at once, and to every other selected topic
    as it appears."""

    def __init__(self, node, selection, tty: bool) -> None:
        self.node, self.selection = node, selection
        self.recording = None                            # the bag, once open_bag made it (callbacks run after)
        self.write_error: type[Exception] = RuntimeError  # BagWriteError once rosbags is imported
        self.line_start = "\r" + CLEAR_EOL if tty else ""  # overwrite the status line on a terminal
        self.subscriptions: dict[str, object] = {}
        self.skipped: set[str] = set()
        self.ahead: dict[str, tuple[object, str]] = {}   # subscribed before discovery: (class, type), until publishers show

    def subscribe_known(self) -> None:
        """Subscribe to the graph's known topics (:mod:`raspv_bags.known_topics`) with the QoS
        their nodes publish with, before any publisher is discovered (and before the bag is
        open: :meth:`open_bag` declares them)."""
        from raspv_bags.known_topics import known_topics
        from raspv_common.ros_introspection import message_class
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        for name, msgtype, latched in known_topics(self.selection.wants):
            try:
                cls = message_class(msgtype)
            except ValueError:
                continue                                 # not installed here: discovery will say so
            qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=RECORD_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
            self.subscriptions[name] = self._subscribe(cls, name, qos)
            self.ahead[name] = (cls, msgtype)

    def open_bag(self, out: Path, storage: str, flush_interval_s: float, compression: str | None = None):
        """Create the bag and declare the topics subscribed ahead (their types made known to
        the bag's typestore; a type it cannot describe is not recorded)."""
        from raspv_bags.known_topics import KNOWN_TOPICS
        from raspv_bags.message_types import ensure_type
        from raspv_bags.recording import Recording
        from raspv_bags.writer import BagWriteError, QosSpec

        try:
            recording = Recording(out, storage, flush_interval_s=flush_interval_s, compression=compression)
        except BagWriteError as exc:
            raise _BagOpenError(str(exc)) from None
        recording.on_first_message = self._first_message
        self.write_error = BagWriteError
        for name, (_cls, msgtype) in list(self.ahead.items()):
            if not ensure_type(msgtype):
                self.ahead.pop(name)
                self._stop_recording(name, f"no message definition found for {msgtype}")
                continue
            latched = KNOWN_TOPICS[name][1]
            recording.expect_topic(name, msgtype, [QosSpec(reliable=True, transient_local=latched, depth=10)])
        self.recording = recording
        return recording

    def _subscribe(self, cls, name: str, qos):
        def on_message(data, info, topic=name):
            # the time the middleware received it: a message that waited in the history while
            # the bag opened (or the writer was busy) keeps its real arrival time
            received = info.get("received_timestamp") or time.time_ns()
            try:
                self.recording.on_message(topic, data, received, info.get("publication_sequence_number") or 0)
            except self.write_error as exc:              # this topic cannot be recorded
                self._stop_recording(topic, str(exc))
        return self.node.create_subscription(cls, name, on_message, qos, raw=True)

    def _stop_recording(self, name: str, why: str) -> None:
        sub = self.subscriptions.pop(name, None)
        if sub is not None:
            self.node.destroy_subscription(sub)
        self._skip(name, why)

    def _first_message(self, name: str, msgtype: str) -> None:
        from raspv_common.startup_timing import startup_mark
        from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
        startup_mark(f"first message of {name}")
        sub = self.subscriptions.get(name)
        qos = sub.qos_profile if sub is not None else None
        kind = "reliable" if qos is None or qos.reliability == ReliabilityPolicy.RELIABLE else "best-effort"
        if qos is not None and qos.durability == DurabilityPolicy.TRANSIENT_LOCAL:
            kind += ", transient-local"
        print(f"{self.line_start}+ {name} [{msgtype}] ({kind})", file=sys.stderr, flush=True)

    def _check_ahead(self, name: str, infos) -> None:
        """A topic subscribed before discovery now has publishers: keep the subscription if it
        matches them all (our nodes), else subscribe again with the QoS they offer."""
        from raspv_bags.writer import QosSpec
        from raspv_common.ros_introspection import qos_matching_publishers
        from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

        cls, msgtype = self.ahead.pop(name)
        offered = [QosSpec(reliable=i.qos_profile.reliability == ReliabilityPolicy.RELIABLE,
                           transient_local=i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL,
                           depth=i.qos_profile.depth if i.qos_profile.depth > 0 else 10) for i in infos]
        self.recording.expect_topic(name, msgtype, offered)      # the bag keeps what was really offered
        qos = qos_matching_publishers(self.node, name)
        sub = self.subscriptions[name]
        if qos.reliability == sub.qos_profile.reliability and qos.durability == sub.qos_profile.durability:
            return
        qos.depth = RECORD_DEPTH
        self.node.destroy_subscription(sub)
        self.subscriptions[name] = self._subscribe(cls, name, qos)
        kind = ("reliable" if qos.reliability == ReliabilityPolicy.RELIABLE else "best-effort") + \
               (", transient-local" if qos.durability == DurabilityPolicy.TRANSIENT_LOCAL else "")
        print(f"{self.line_start}{name}: publishers offer {kind}; subscribed again to match", file=sys.stderr,
              flush=True)

    def discover(self) -> None:
        from raspv_bags.message_types import ensure_type
        from raspv_bags.writer import BagWriteError, QosSpec
        from raspv_common.ros_introspection import message_class, qos_matching_publishers
        from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

        for name, types in self.node.get_topic_names_and_types():
            if name in self.ahead:
                if types == [self.ahead[name][1]]:
                    infos = self.node.get_publishers_info_by_topic(name)
                    if infos:
                        self._check_ahead(name, infos)
                    continue
                # published with another type than the known one: subscribed anew below
            elif name in self.subscriptions or name in self.skipped or not self.selection.wants(name):
                continue
            infos = self.node.get_publishers_info_by_topic(name)
            if not infos:
                continue  # only subscribers so far: wait for a publisher
            if len(types) != 1:
                self._skip(name, f"published with several types ({', '.join(types)})")
                continue
            msgtype = types[0]
            try:
                cls = message_class(msgtype)
            except ValueError:
                self._skip(name, f"message type {msgtype} is not installed")
                continue
            if not ensure_type(msgtype):
                self._skip(name, f"no message definition found for {msgtype}")
                continue
            offered = [QosSpec(reliable=i.qos_profile.reliability == ReliabilityPolicy.RELIABLE,
                               transient_local=i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL,
                               depth=i.qos_profile.depth if i.qos_profile.depth > 0 else 10) for i in infos]
            qos = qos_matching_publishers(self.node, name)
            qos.depth = RECORD_DEPTH  # never drop while the writer is busy with a large message
            try:
                self.recording.add_topic(name, msgtype, offered)
            except BagWriteError as exc:
                self._skip(name, str(exc))
                continue
            if name in self.subscriptions:          # a known topic published with another type
                self.node.destroy_subscription(self.subscriptions.pop(name))
                self.ahead.pop(name, None)
            self.subscriptions[name] = self._subscribe(cls, name, qos)
            kind = ("reliable" if qos.reliability == ReliabilityPolicy.RELIABLE else "best-effort") + \
                   (", transient-local" if qos.durability == DurabilityPolicy.TRANSIENT_LOCAL else "")
            print(f"{self.line_start}+ {name} [{msgtype}] ({kind})", file=sys.stderr, flush=True)

    def _skip(self, name: str, why: str) -> None:
        self.skipped.add(name)
        print(f"{self.line_start}raspv bag record: skipping {name}: {why}", file=sys.stderr, flush=True)
