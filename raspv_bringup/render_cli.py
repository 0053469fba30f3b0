"""`raspv render BAG -o out.mp4`: a bag → phosphene video (and/or PNG frames), offline.

Runs the phosphene simulator of the ``spv`` node (:mod:`raspv_bags.render`) as fast as
the machine allows, with a progress bar.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import yaml


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", help="bag directory or .mcap/.db3 file")
    parser.add_argument("-o", "--output", metavar="VIDEO", help="mp4 file to write")
    parser.add_argument("--png-dir", metavar="DIR", help="also (or only) write every frame as a PNG here")
    parser.add_argument("--codec", choices=("mp4v", "h264"), default="mp4v",
                        help="the video's codec: mp4v (default; desktop players) or h264 (plays in browsers too; "
                             "needs the 'video' extra)")
    spv = parser.add_argument_group("phosphenes (the spv node's parameters; defaults as the node's)")
    spv.add_argument("--params", metavar="FILE", help="take the spv parameters from a graph or parameter file "
                                                      "(its 'spv' section)")
    spv.add_argument("--device", help="device preset or YAML file (default: default)")
    spv.add_argument("--mode", help="representation mode (default: grey)")
    spv.add_argument("--overlay", action="append", default=None, metavar="NAME", help="overlay on top of the mode")
    spv.add_argument("--width", type=int, help="phosphene image width [px] (default 800)")
    spv.add_argument("--rate", type=float, metavar="HZ",
                     help="display rate = video frame rate = temporal model rate (default 50)")
    spv.add_argument("--no-temporal", action="store_true", help="without the temporal model")
    spv.add_argument("--green", action="store_true", help="green phosphenes (as in the headset)")
    spv.add_argument("--max-depth", type=float, metavar="M", help="depth modes: depth shown as level 0")
    spv.add_argument("--dropout", type=float, help="fraction of phosphenes that never light")
    spv.add_argument("--noise", type=float, metavar="PX", help="displayed position noise [px]")
    spv.add_argument("--seed", type=int, help="seed of dropout and noise")
    spv.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                     help="any other spv parameter, e.g. --set num_phosphenes=500 (see `raspv nodes`)")
    spv.add_argument("--scene-set", action="append", default=[], metavar="NAME=VALUE",
                     help="a scene node parameter for the scene modes, e.g. --scene-set stride=2")
    parser.add_argument("--shown", action="store_true",
                        help="the wearer's view as it was shown, re-rendered from the recorded /spv/frame and "
                             "/spv/sprites (the default recording has no /spv/image); the phosphene options are "
                             "then the recording's own")
    parser.add_argument("--side-by-side", action="store_true",
                        help="colour image and the mode's other inputs (depth) next to the phosphenes")
    parser.add_argument("--start", type=float, default=0.0, metavar="S", help="start S seconds into the bag")
    parser.add_argument("--duration", type=float, default=None, metavar="S", help="render at most S seconds")
    cam = parser.add_argument_group("intrinsics when the bag has no camera info")
    cam.add_argument("--intrinsics", metavar="FILE", help="YAML with fx, fy, cx, cy (or a ROS calibration file)")
    for k in ("fx", "fy", "cx", "cy"):
        cam.add_argument(f"--{k}", type=float, default=None, help=f"{k} [px]")
    parser.add_argument("--color-topic", default=None, help="colour topic (default /camera/color/image_raw)")
    parser.add_argument("--depth-topic", default=None, help="depth topic (default /camera/depth/image_raw)")
    parser.add_argument("--info-topic", default=None, help="camera info topic (default /camera/color/camera_info)")


def _file_section(path: str, node: str, required: bool) -> dict:
    """``node: ros__parameters:`` of a graph or parameter file (ValueError if unreadable)."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: cannot read ({exc})") from None
    section = data.get(node) if isinstance(data, dict) else None
    if section is None and not required:
        return {}
    if not isinstance(section, dict) or not isinstance(section.get("ros__parameters") or {}, dict):
        raise ValueError(f"{path}: no '{node}: ros__parameters:' section")
    return dict(section.get("ros__parameters") or {})


def _assignments(items: list[str], flag: str) -> dict:
    out = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"bad {flag} {item!r}: expected NAME=VALUE")
        out[name.strip()] = yaml.safe_load(text)
    return out


def _scene_params(args: argparse.Namespace) -> dict:
    """scene parameter values from --params FILE (its 'scene' section), then --scene-set."""
    out = _file_section(args.params, "scene", required=False) if args.params else {}
    out.update(_assignments(args.scene_set, "--scene-set"))
    return out


def _spv_params(args: argparse.Namespace) -> dict:
    """spv parameter values from --params FILE, then the flags, then --set (ValueError if bad)."""
    out: dict = _file_section(args.params, "spv", required=True) if args.params else {}
    flags = {"device": args.device, "mode": args.mode, "width": args.width, "rate": args.rate,
             "max_depth": args.max_depth, "dropout": args.dropout, "noise_px": args.noise, "seed": args.seed,
             "overlays": args.overlay}
    out.update({k: v for k, v in flags.items() if v is not None})
    if args.no_temporal:
        out["temporal"] = False
    if args.green:
        out["output_format"] = "green"
    out.update(_assignments(args.set, "--set"))
    return out


def _render_shown(args: argparse.Namespace, fail) -> int:
    """``--shown``: the recorded view, frame by frame (:mod:`raspv_bags.shown_render`)."""
    import cv2
    import numpy as np

    from raspv_bags.reader import BagError, BagReader
    from raspv_bags.shown_render import ShownRenderError, shown_images
    from raspv_bags.video_sink import VideoError, VideoSink

    sink, frames, stamps, other_size = None, 0, [], 0
    png_dir = Path(args.png_dir) if args.png_dir else None
    if png_dir is not None:
        png_dir.mkdir(parents=True, exist_ok=True)
    try:
        with BagReader(args.bag) as reader:
            first = reader.start_ns / 1e9 if reader.start_ns is not None else 0.0
            for shown in shown_images(reader):
                if shown.stamp < first + args.start or (args.duration is not None
                                                        and shown.stamp >= first + args.start + args.duration):
                    continue
                image = shown.image
                if sink is None and args.output:
                    sink = VideoSink(Path(args.output), _rate(reader), image.shape[1::-1], image.ndim == 3, args.codec)
                if sink is not None and image.shape[1::-1] != sink.size:
                    other_size += 1                  # a device change: another map size (PNGs keep them)
                elif sink is not None:
                    sink.write(image)
                if png_dir is not None:
                    cv2.imwrite(str(png_dir / f"frame_{frames:06d}.png"), image if image.ndim == 2 else image[..., ::-1])
                frames += 1
                stamps.append(shown.stamp)
            notes = list(reader.notes)
        if sink is not None:
            sink.close()
    except (ShownRenderError, BagError, VideoError) as exc:
        return fail(str(exc))
    for note in notes + ([f"{other_size} frames of another map size are not in the video"] if other_size else []):
        print(f"note: {note}", file=sys.stderr)
    if not frames:
        return fail(f"{args.bag}: no /spv/frame with its map's /spv/sprites in the chosen time range")
    span = stamps[-1] - stamps[0] if len(stamps) > 1 else 0.0
    outputs = " and ".join(str(p) for p in (args.output, args.png_dir) if p)
    print(f"{outputs}: {frames} frames as shown ({span:.1f} s, {np.median(np.diff(stamps)) * 1e3 if len(stamps) > 1 else 0:.0f} "
          f"ms apart)")
    return 0


def _rate(reader) -> float:
    """The display rate of a recording's /spv/frame [Hz] (its count over its time span)."""
    info = reader.topics["/spv/frame"]
    span = (reader.end_ns - reader.start_ns) / 1e9 if reader.end_ns and reader.start_ns else 0.0
    return max(1.0, min(120.0, info.count / span)) if span > 0 else 50.0


def _bar(done: float, total: float, started: float, width: int = 30) -> str:
    frac = min(1.0, done / total) if total > 0 else 1.0
    n = int(round(frac * width))
    elapsed = time.monotonic() - started
    speed = done / elapsed if elapsed > 0 else 0.0
    return f"\r[{'#' * n}{'.' * (width - n)}] {done:6.1f}/{total:.1f} s of bag  {speed:5.1f}x real time"


def run(args: argparse.Namespace) -> int:
    from raspv_bags.from_frames import FramesError, load_intrinsics_file
    from raspv_bags.reader import BagError
    from raspv_bags.render import RenderError, RenderSettings, render_bag

    def fail(text: str) -> int:
        print(f"raspv render: {text}", file=sys.stderr)
        return 1

    if not args.output and not args.png_dir:
        return fail("give an output: -o out.mp4 and/or --png-dir DIR")
    if args.output and Path(args.output).suffix.lower() != ".mp4":
        return fail(f"{args.output}: the video must be an .mp4 file")
    if args.output:
        from raspv_bags.video_sink import require_codec

        require_codec(args.codec)  # its extra missing: MissingExtra, one line from `raspv` naming the install
    if args.shown:
        return _render_shown(args, fail)
    given = [k for k in ("fx", "fy", "cx", "cy") if getattr(args, k) is not None]
    if given and len(given) < 4:
        return fail("give all of --fx --fy --cx --cy")
    intrinsics = None
    if given:
        intrinsics = {k: getattr(args, k) for k in ("fx", "fy", "cx", "cy")}
    elif args.intrinsics:
        try:
            intrinsics = load_intrinsics_file(Path(args.intrinsics))
        except FramesError as exc:
            return fail(str(exc))
    try:
        spv, scene = _spv_params(args), _scene_params(args)
    except ValueError as exc:
        return fail(str(exc))
    s = RenderSettings(spv=spv, scene=scene, side_by_side=args.side_by_side, start_s=args.start,
                       duration_s=args.duration, intrinsics=intrinsics, codec=args.codec)
    for attr in ("color_topic", "depth_topic", "info_topic"):
        if getattr(args, attr):
            setattr(s, attr, getattr(args, attr))
    tty = sys.stderr.isatty()
    started = time.monotonic()

    def progress(done: float, total: float) -> None:
        if tty:
            print(_bar(done, total, started), end="", file=sys.stderr, flush=True)

    try:
        report = render_bag(args.bag, args.output, args.png_dir, s, progress)
    except (RenderError, BagError) as exc:
        if tty:
            print(file=sys.stderr)
        return fail(str(exc))
    if tty:
        print(file=sys.stderr)
    for note in report.notes:
        print(f"note: {note}", file=sys.stderr)
    outputs = " and ".join(str(p) for p in (report.video, report.png_dir) if p is not None)
    print(f"{outputs}: {report.frames} frames {report.size[0]}x{report.size[1]} at {report.rate:g} Hz from "
          f"{report.camera_frames} camera frames ({report.bag_s:.1f} s of bag in {report.wall_s:.1f} s, "
          f"{report.speed:.1f}x real time)")
    return 0
