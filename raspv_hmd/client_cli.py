"""`raspv hmd-client URL`: the Python reference headset client — receives frames, sends a
scripted head motion, measures frame rate and latency (see raspv_hmd/reference_client.py)."""
from __future__ import annotations

import argparse
import asyncio
import json
import sys

from raspv_hmd.reference_client import (ClientError, ClientOptions, HeadScript, parse_endpoint, percentile,
                                        run_client)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("url", help="the URL the bridge printed (http://127.0.0.1:8765/), or tcp://HOST:PORT")
    parser.add_argument("--token", default="", help="the bridge's token (when not in the URL)")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds to run (default 10)")
    parser.add_argument("--frames", type=int, default=None, help="stop after this many frames")
    parser.add_argument("--watch", action="store_true", help="only watch: never ask for control")
    parser.add_argument("--format", choices=("auto", "raw", "png"), default="auto",
                        help="frame encoding to ask for (default auto: PNG for remote bridges)")
    parser.add_argument("--no-head", action="store_true", help="do not send the scripted head motion")
    parser.add_argument("--yaw", type=float, default=30.0, help="head yaw amplitude [deg] (default 30)")
    parser.add_argument("--period", type=float, default=4.0, help="head sweep period [s] (default 4)")
    parser.add_argument("--save-frame", metavar="PNG", help="write the last frame received to this file")
    parser.add_argument("--json", action="store_true", help="print the full report as JSON")


def run(args: argparse.Namespace) -> int:
    try:
        endpoint = parse_endpoint(args.url, args.token)
    except ValueError as exc:
        print(f"raspv hmd-client: {exc}", file=sys.stderr)
        return 2
    if not args.duration > 0 or (args.frames is not None and args.frames < 1) or not args.period > 0:
        print("raspv hmd-client: --duration and --period must be > 0 and --frames >= 1", file=sys.stderr)
        return 2
    options = ClientOptions(role="watch" if args.watch else "control", format=args.format,
                            duration_s=args.duration, max_frames=args.frames,
                            head=None if args.no_head else HeadScript(yaw_deg=args.yaw, period_s=args.period),
                            keep_last_frame=bool(args.save_frame))
    try:
        report = asyncio.run(run_client(endpoint, options))
    except ClientError as exc:
        print(f"raspv hmd-client: {exc}", file=sys.stderr)
        return 1
    if args.save_frame and report.last_frame is not None:
        import cv2
        img = report.last_frame if report.last_frame.ndim == 2 else cv2.cvtColor(report.last_frame, cv2.COLOR_RGB2BGR)
        if not cv2.imwrite(args.save_frame, img):
            print(f"raspv hmd-client: cannot write {args.save_frame}", file=sys.stderr)
            return 1
    if args.json:
        print(json.dumps(report.to_json()))
        return 0
    print(summary(report, args.save_frame))
    return 0 if report.frames else 1


def summary(report, saved: str | None = None) -> str:
    def ms(values: list[float]) -> str:
        if not values:
            return "n/a"
        return f"p50 {percentile(values, 50):.1f} ms, p95 {percentile(values, 95):.1f} ms"

    size = f"{report.size[0]}x{report.size[1]}" if report.size else "no frames"
    formats = ", ".join(f"{k} {v}" for k, v in report.formats_seen.items()) or "-"
    lines = [f"client {report.client_id} ({report.transport}, {report.role}): {report.frames} frames {size} in "
             f"{report.elapsed_s:.1f} s → {report.fps:.1f} fps; formats: {formats}; "
             f"{report.bytes / max(report.elapsed_s, 1e-9) / 1e6:.1f} MB/s",
             f"  image time → received: {ms(report.latency_ms)}"
             + (f" (clock offset {1e3 * report.clock_offset_s:+.1f} ms)" if report.clock_offset_s is not None else ""),
             f"  round trip (ping/pong): {ms(report.rtt_ms)}",
             f"  head orientations sent: {len(report.heads_sent)}"]
    for m in report.messages:
        if m["type"] in ("status", "refused", "bye"):
            lines.append(f"  server {m['type']}: {m.get('text') or m.get('reason')}")
    if report.closed:
        lines.append(f"  closed: {report.closed}")
    if saved and report.last_frame is not None:
        lines.append(f"  last frame written to {saved}")
    return "\n".join(lines)
