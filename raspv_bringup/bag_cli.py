"""`raspv bag record|play|info|repair|from-frames` — ROS 2 bags without rosbag2.

- ``record [TOPICS…] -o DIR``: raw subscriptions (bytes written unchanged) with QoS matched to
  the publishers, topics that appear later picked up, live counts on one status line; Ctrl-C
  or SIGTERM closes a complete bag; a SIGKILLed recording stays readable (``repair`` makes it
  complete for other tools).
- ``play BAG``: the ``replay`` node in this process (original timing, rate, loop, remapping,
  ``/clock``; timing error at the end).
- ``info BAG``: topics, types, counts, rates, QoS, what is wrong with a damaged bag, and — for a
  recording of ``/spv/frame`` — the share of frames shown in the configured representation and
  the fallbacks shown instead (:mod:`raspv_bags.shown_frames`).
- ``repair BAG``: a complete copy of everything readable.
- ``from-frames DIR -o BAG``: a bag from colour/depth image folders (TUM layout and others).
"""
from __future__ import annotations

import argparse
import datetime as dt
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

import yaml

from raspv_bringup.middleware import apply_middleware_defaults

ACTIONS = ("record", "play", "info", "repair", "from-frames")
CLEAR_EOL = "\x1b[K"  # erase the rest of a terminal line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="bag_action", metavar="ACTION", required=True)

    rec = sub.add_parser("record", help="record topics of the running graph into a bag",
                         description="Record topics of the running graph. Without TOPICS: every topic "
                                     "(except /rosout, /parameter_events) but the images their node renders only for a "
                                     "subscriber: the phosphene image /spv/image, which /spv/frame, /spv/map and "
                                     "/spv/sprites re-render (raspv render BAG --shown), and the simulator's "
                                     "/sim/labels; --images or naming them records them.")
    rec.add_argument("topics", nargs="*", metavar="TOPIC", help="topic names or patterns like '/camera/*'")
    rec.add_argument("-o", "--output", metavar="DIR", help="bag directory to create (default rosbag2_<date>)")
    rec.add_argument("-x", "--exclude", nargs="+", default=[], metavar="TOPIC", help="topics/patterns to leave out")
    rec.add_argument("--images", action="store_true",
                     help="also record the images rendered only for a subscriber: /spv/image (800x800 at 50 Hz; "
                          "spv then renders it) and /sim/labels (the simulator then renders them)")
    rec.add_argument("-s", "--storage", choices=("mcap", "sqlite3"), default="mcap", help="storage format (default mcap)")
    rec.add_argument("--compression", choices=("zstd", "lz4", "none"), default=None,
                     help="lossless compression of the MCAP chunks, which every MCAP reader undoes (default zstd; "
                          "sqlite3 bags are uncompressed)")
    rec.add_argument("-d", "--duration", type=float, default=None, metavar="S", help="stop after S seconds")
    rec.add_argument("--flush-interval", type=float, default=0.5, metavar="S",
                     help="seconds between flushes to disk: at most this much is lost if the recorder is killed "
                          "(default 0.5)")

    play = sub.add_parser("play", help="publish a bag's messages with their original timing",
                          description="Publish a bag into the graph (the replay node, run in this process).")
    play.add_argument("bag", help="bag directory or .mcap/.db3 file")
    play.add_argument("-r", "--rate", type=float, default=1.0, help="speed factor (default 1.0)")
    play.add_argument("--start", type=float, default=0.0, metavar="S", help="start S seconds into the bag")
    play.add_argument("-l", "--loop", action="store_true", help="play again from the start at the end")
    play.add_argument("--topics", nargs="+", default=[], metavar="TOPIC", help="play only these topics")
    play.add_argument("-x", "--exclude", nargs="+", default=[], metavar="TOPIC", help="do not play these topics")
    play.add_argument("--remap", nargs="+", default=[], metavar="FROM:=TO", help="publish a topic under another name")
    play.add_argument("--no-clock", action="store_true", help="do not publish /clock")
    play.add_argument("--clock-rate", type=float, default=100.0, metavar="HZ", help="/clock rate (default 100)")
    play.add_argument("--delay", type=float, default=0.0, metavar="S", help="wait S seconds before playing")
    play.add_argument("--wait-for-subscribers", type=int, default=0, metavar="N",
                      help="start once the played topics have N subscriptions in all (at most 30 s)")

    info = sub.add_parser("info", help="topics, counts, rates and problems of a bag")
    info.add_argument("bag", help="bag directory or .mcap/.db3 file")

    rep = sub.add_parser("repair", help="write a complete copy of an unfinished or damaged bag",
                         description="Copy everything readable from BAG into a new complete bag "
                                     "(e.g. after the recorder was killed). BAG itself is not changed.")
    rep.add_argument("bag", help="bag directory or .mcap/.db3 file")
    rep.add_argument("-o", "--output", metavar="DIR", help="new bag directory (default <BAG>-repaired)")
    rep.add_argument("-s", "--storage", choices=("mcap", "sqlite3"), default=None, help="default: as the source")

    ff = sub.add_parser("from-frames", help="build a bag from folders of colour/depth images",
                        description="Build a bag (colour rgb8, depth 32FC1, camera_info, optional pose) from "
                                    "RGB-D image files: a TUM sequence (rgb.txt, depth.txt, groundtruth.txt), "
                                    "folders of colour/depth images, or single colour/depth pairs.")
    ff.add_argument("source", nargs="?", help="folder with the frames (not needed with --color/--depth)")
    ff.add_argument("-o", "--output", required=True, metavar="DIR", help="bag directory to create")
    ff.add_argument("--color", nargs="+", default=[], metavar="FILE", help="colour image files (with --depth)")
    ff.add_argument("--depth", nargs="+", default=[], metavar="FILE", help="depth image files, same order")
    ff.add_argument("--fps", type=float, default=30.0, help="frame rate when the files hold no timestamps (default 30)")
    ff.add_argument("--start-time", type=float, default=None, metavar="S",
                    help="first timestamp [s since the epoch] with --fps (default: now)")
    ff.add_argument("--depth-format", choices=("auto", "tum", "mm", "nyu", "metres"), default="auto",
                    help="depth encoding: tum (uint16/5000), mm (uint16 millimetres), nyu (NYU v2 raw disparity), "
                         "metres (float images); auto: tum for TUM sequences, else mm/metres by pixel type")
    ff.add_argument("--depth-scale", type=float, default=None, metavar="M", help="metres per unit of uint16 depth")
    ff.add_argument("--groundtruth", metavar="FILE", help="TUM groundtruth.txt for /camera/pose "
                                                          "(found automatically in a TUM sequence)")
    ff.add_argument("--max-dt", type=float, default=0.02, metavar="S",
                    help="largest colour/depth/pose time difference when associating by timestamp (default 0.02)")
    cam = ff.add_argument_group("camera intrinsics (one of)")
    cam.add_argument("--camera", choices=("primesense", "tum-fr1", "tum-fr2", "tum-fr3", "xtion-60deg"),
                     help="a preset (640x480 values, rescaled to the image size)")
    cam.add_argument("--intrinsics", metavar="FILE", help="YAML with fx, fy, cx, cy [, width, height] "
                                                          "or a ROS camera-calibration file")
    for k in ("fx", "fy", "cx", "cy"):
        cam.add_argument(f"--{k}", type=float, default=None, help=f"{k} [px]")
    ff.add_argument("-s", "--storage", choices=("mcap", "sqlite3"), default="mcap", help="storage format (default mcap)")


def run(args: argparse.Namespace) -> int:
    return {"record": _record, "play": _play, "info": _info, "repair": _repair,
            "from-frames": _from_frames}[args.bag_action](args)


def _err(action: str, text: str) -> int:
    print(f"raspv bag {action}: {text}", file=sys.stderr)
    return 1


# -- record -------------------------------------------------------------------------------------

def _record(args: argparse.Namespace) -> int:
    """Capture first, write second: the subscriptions to the known topics are made before the
    bag is opened and rosbags' message types are loaded (≈0.4 s of CPU, issue 27), and the
    messages that arrive meanwhile wait in each subscription's history (100 deep) and enter
    the bag with the time the middleware received them."""
    from raspv_bags.recording import TopicSelection
    from raspv_common.startup_timing import startup_mark
    startup_mark("command started")

    if args.duration is not None and args.duration <= 0:
        return _err("record", f"--duration must be > 0, got {args.duration}")
    if args.flush_interval <= 0:
        return _err("record", f"--flush-interval must be > 0, got {args.flush_interval}")
    out = Path(args.output or dt.datetime.now().strftime("rosbag2_%Y_%m_%d-%H_%M_%S"))
    if out.exists():                     # BagWriter says so too; here before any ROS start-up
        return _err("record", f"{out} exists already; choose a new output directory")
    if not out.absolute().parent.is_dir():
        return _err("record", f"{out.absolute().parent} is not a directory")
    if args.storage != "mcap" and args.compression not in (None, "none"):
        return _err("record", f"--compression {args.compression} is for MCAP bags (their chunks); "
                              f"{args.storage} bags are written uncompressed")
    selection = TopicSelection(tuple(args.topics), tuple(args.exclude), images=args.images)

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
        return _err("record", str(exc))
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
            qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
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
                self.recording.on_message(topic, data, received)
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
        qos.depth = 100
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
            qos.depth = 100  # never drop while the writer is busy with a large message
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


# -- play ---------------------------------------------------------------------------------------

def _play(args: argparse.Namespace) -> int:
    from raspv_bags.playback import parse_remap

    if not args.rate > 0:
        return _err("play", f"--rate must be > 0, got {args.rate}")
    if args.start < 0:
        return _err("play", f"--start must be >= 0, got {args.start}")
    if args.delay < 0 or args.wait_for_subscribers < 0:
        return _err("play", "--delay and --wait-for-subscribers must be >= 0")
    try:
        parse_remap(args.remap)
    except ValueError as exc:
        return _err("play", str(exc))
    if not Path(args.bag).exists():
        return _err("play", f"{args.bag}: no such bag")
    params = {"bag": str(Path(args.bag).resolve()), "rate": float(args.rate), "start_offset": float(args.start),
              "loop": bool(args.loop), "topics": list(args.topics), "exclude_topics": list(args.exclude),
              "remap": list(args.remap), "publish_clock": not args.no_clock,
              "clock_rate": float(args.clock_rate), "at_end": "exit", "progress": sys.stderr.isatty(),
              "delay": float(args.delay), "wait_for_subscribers": int(args.wait_for_subscribers)}
    # An empty list in a parameter file reaches rclpy as "not set": leave empty lists out.
    params = {k: v for k, v in params.items() if v != []}
    apply_middleware_defaults()
    from raspv_camera.replay_node import ReplayNode
    from raspv_common.node import run_node

    with tempfile.NamedTemporaryFile("w", suffix=".yaml", prefix="raspv-play-", delete=False) as f:
        yaml.safe_dump({"/**": {"ros__parameters": params}}, f)
    try:
        run_node(ReplayNode, ["raspv-bag-play", "--ros-args", "--params-file", f.name, "--disable-rosout-logs"])
    except SystemExit as exc:
        return int(exc.code or 0)
    finally:
        os.unlink(f.name)
    return 0


# -- info ---------------------------------------------------------------------------------------

def _info(args: argparse.Namespace) -> int:
    from raspv_bags.reader import BagError, BagReader

    try:
        reader = BagReader(args.bag)
    except BagError as exc:
        return _err("info", str(exc))
    with reader:
        print(format_info(reader))
    return 0


def format_info(reader) -> str:
    """Human summary of an open :class:`~raspv_bags.reader.BagReader`."""
    lines = [f"bag:       {reader.path}",
             f"storage:   {reader.storage}" + ("" if reader.complete else "  (INCOMPLETE: see notes)")]
    if reader.start_ns is not None:
        start = dt.datetime.fromtimestamp(reader.start_ns * 1e-9).isoformat(sep=" ", timespec="milliseconds")
        lines.append(f"duration:  {reader.duration_s:.3f} s  (start {start})")
    lines.append(f"messages:  {reader.message_count}")
    lines.append("topics:")
    for t in sorted(reader.topics.values(), key=lambda t: t.name):
        hz = reader.topic_rate_hz(t.name)         # over the topic's own first-to-last span
        rate = f"{hz:6.1f} Hz" if hz is not None else "       -"
        qos = ""
        if t.qos:
            q = t.qos[0]
            qos = ("reliable" if q.reliable else "best-effort") + (" transient-local" if q.transient_local else "")
        unknown = "" if t.known_type else "  (unknown type)"
        lines.append(f"  {t.name:38s} {t.count:7d}  {rate}  {t.msgtype}  {qos}{unknown}")
    share = _shown(reader)
    if share is not None:
        lines.append(f"shown:     {share}")
    for note in reader.notes:
        lines.append(f"note: {note}")
    return "\n".join(lines)


def _shown(reader) -> str | None:
    """What the wearer saw (/spv/frame), one line; None without that topic."""
    from raspv_bags.shown_frames import bag_shown_share

    try:
        share = bag_shown_share(reader)
    except Exception as exc:  # noqa: BLE001 - a frame that does not decode: say so, keep the rest of info
        return f"/spv/frame could not be read ({type(exc).__name__}: {exc})"
    return None if share is None else share.describe()


# -- repair -------------------------------------------------------------------------------------

def _repair(args: argparse.Namespace) -> int:
    from raspv_bags.reader import BagError
    from raspv_bags.repair import repair_bag
    from raspv_bags.writer import BagWriteError

    src = Path(args.bag)
    out = Path(args.output) if args.output else src.with_name((src.stem if src.is_file() else src.name) + "-repaired")
    tty = sys.stderr.isatty()

    def progress(done: int, total: int) -> None:
        if tty:
            print(f"\r{done}/{total} messages", end="", file=sys.stderr, flush=True)

    try:
        report = repair_bag(src, out, args.storage, progress)
    except (BagError, BagWriteError) as exc:
        return _err("repair", str(exc))
    if tty:
        print(file=sys.stderr)
    for note in report.notes:
        print(f"note: {note}", file=sys.stderr)
    print(f"{out}: complete bag with {report.message_count} messages "
          f"({', '.join(f'{t} {n}' for t, n in sorted(report.counts.items()))})")
    return 0


# -- from-frames --------------------------------------------------------------------------------

def _from_frames(args: argparse.Namespace) -> int:
    from raspv_bags.from_frames import (CAMERA_PRESETS, FramesError, discover_frames, load_intrinsics_file,
                                              write_frames_bag)
    from raspv_bags.writer import BagWriteError

    given = [k for k in ("fx", "fy", "cx", "cy") if getattr(args, k) is not None]
    try:
        if given and len(given) < 4:
            raise FramesError(f"give all of --fx --fy --cx --cy (missing {', '.join(k for k in ('fx', 'fy', 'cx', 'cy') if k not in given)})")
        if sum(bool(x) for x in (given, args.intrinsics, args.camera)) > 1:
            raise FramesError("give the intrinsics one way: --fx/--fy/--cx/--cy, --intrinsics or --camera")
        frames = discover_frames(Path(args.source) if args.source else None, args.color, args.depth, fps=args.fps,
                                 start_s=args.start_time, depth_format=args.depth_format,
                                 depth_scale=args.depth_scale,
                                 groundtruth=Path(args.groundtruth) if args.groundtruth else None,
                                 max_dt_s=args.max_dt)
        if given:
            intr = {k: getattr(args, k) for k in ("fx", "fy", "cx", "cy")}
        elif args.intrinsics:
            intr = load_intrinsics_file(Path(args.intrinsics))
        elif args.camera:
            fx, fy, cx, cy = CAMERA_PRESETS[args.camera]
            intr = {"fx": fx, "fy": fy, "cx": cx, "cy": cy, "width": 640, "height": 480}
        elif args.source and (Path(args.source) / "intrinsics.yaml").is_file():     # the folder's own
            intr = load_intrinsics_file(Path(args.source) / "intrinsics.yaml")
            print(f"intrinsics from {Path(args.source) / 'intrinsics.yaml'}", file=sys.stderr)
        else:
            intr = None
        print(f"{len(frames.pairs)} frames ({frames.layout} layout, depth {frames.depth_format})", file=sys.stderr)
        tty = sys.stderr.isatty()

        def progress(done: int, total: int) -> None:
            if tty:
                print(f"\r{_bar(done, total)}", end="", file=sys.stderr, flush=True)

        report = write_frames_bag(frames, intr, Path(args.output), args.storage, progress)
        if tty:
            print(file=sys.stderr)
    except (FramesError, BagWriteError) as exc:
        return _err("from-frames", str(exc))
    for note in report.notes:
        print(f"note: {note}", file=sys.stderr)
    cam = report.intrinsics
    print(f"{report.output}: {report.frames} frames {report.size[0]}x{report.size[1]}"
          f" (fx {cam.fx:.1f}, fy {cam.fy:.1f}, cx {cam.cx:.1f}, cy {cam.cy:.1f})"
          + (f", {report.with_pose} poses" if report.with_pose else "")
          + (f", {report.skipped} skipped" if report.skipped else ""))
    return 0


def _bar(done: int, total: int, width: int = 30) -> str:
    frac = done / total if total else 1.0
    n = int(round(frac * width))
    return f"[{'#' * n}{'.' * (width - n)}] {done}/{total}"
