"""`raspv bag record|play|info|repair|from-frames` — ROS 2 bags without rosbag2.

- ``record [TOPICS…] -o DIR``: raw subscriptions (bytes written unchanged) with QoS matched to
  the publishers, topics that appear later picked up, live counts on one status line; Ctrl-C
  or SIGTERM closes a complete bag; a SIGKILLed recording stays readable (``repair`` makes it
  complete for other tools); behind the graph (:mod:`raspv_bringup.bag_record`).
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
import sys
import tempfile
from pathlib import Path

import yaml

from raspv_bringup.bag_record import err as _err
from raspv_bringup.bag_record import record as _record
from raspv_bringup.middleware import apply_middleware_defaults

ACTIONS = ("record", "play", "info", "repair", "from-frames")


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
    rec.add_argument("--nice", type=int, default=None, metavar="N",
                     help="the recorder's session nice value once recording, 0-19 (default 2: level with the graph's "
                          "cameras; higher yields more but may lose messages on a busy machine, counted)")
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
    ff.add_argument("--distortion", type=float, nargs="+", metavar="K",
                    help="lens distortion of the colour images, plumb bob k1 k2 p1 p2 [k3] (OpenCV's), for the camera "
                         "info (default: the --camera preset's, tum-fr1/tum-fr2 TUM's published one; else none)")
    ff.add_argument("--rolling-shutter", type=float, default=None, metavar="S",
                    help="readout of the colour camera's rolling shutter, first to last row [s], kept in the bag's "
                         "metadata for the slam node (default: the --camera preset's, 0.025 for tum-fr1/tum-fr2; "
                         "else 0, a global shutter)")
    ff.add_argument("-s", "--storage", choices=("mcap", "sqlite3"), default="mcap", help="storage format (default mcap)")


def run(args: argparse.Namespace) -> int:
    return {"record": _record, "play": _play, "info": _info, "repair": _repair,
            "from-frames": _from_frames}[args.bag_action](args)


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
    from raspv_bags.from_frames import (CAMERA_DISTORTION, CAMERA_PRESETS, CAMERA_ROLLING_SHUTTER, FramesError,
                                        discover_frames, load_intrinsics_file, write_frames_bag)
    from raspv_common.intrinsics import OPENCV_DISTORTION_COUNTS
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

        distortion = tuple(args.distortion) if args.distortion else CAMERA_DISTORTION.get(args.camera or "", ())
        if distortion and len(distortion) not in OPENCV_DISTORTION_COUNTS:
            raise FramesError(f"--distortion takes 4, 5 or 8 coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6]]), "
                              f"got {len(distortion)}")
        readout = CAMERA_ROLLING_SHUTTER.get(args.camera or "", 0.0) if args.rolling_shutter is None \
            else args.rolling_shutter
        if not 0 <= readout < 0.1:
            raise FramesError(f"--rolling-shutter takes a readout in [0, 0.1) s, got {readout}")
        report = write_frames_bag(frames, intr, Path(args.output), args.storage, progress, distortion=distortion,
                                  rolling_shutter_readout=readout)
        if tty:
            print(file=sys.stderr)
    except (FramesError, BagWriteError) as exc:
        return _err("from-frames", str(exc))
    for note in report.notes:
        print(f"note: {note}", file=sys.stderr)
    cam = report.intrinsics
    print(f"{report.output}: {report.frames} frames {report.size[0]}x{report.size[1]}"
          f" (fx {cam.fx:.1f}, fy {cam.fy:.1f}, cx {cam.cx:.1f}, cy {cam.cy:.1f})"
          + (f", distortion {' '.join(f'{k:g}' for k in distortion)}" if distortion else "")
          + (f", rolling shutter {readout * 1e3:g} ms" if readout else "")
          + (f", {report.with_pose} poses" if report.with_pose else "")
          + (f", {report.skipped} skipped" if report.skipped else ""))
    return 0


def _bar(done: int, total: int, width: int = 30) -> str:
    frac = done / total if total else 1.0
    n = int(round(frac * width))
    return f"[{'#' * n}{'.' * (width - n)}] {done}/{total}"
