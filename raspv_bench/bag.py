"""Bags: offline render speed vs real time and replay timing error.

Part 1 builds a 640×480, 30 Hz bag from a real RGB-D frame (the TUM desk, moved a little every
frame so nothing is cached by accident) and renders it with ``raspv render``'s core at the
default settings (device preset, grey mode, temporal model on, 800×800 at 50 Hz, mp4), then
with the depth mode and side by side. Target: ≥ 5× real time with the default preset.

Part 2 plays that bag with ``raspv bag play`` in a subprocess on a private ROS domain and
measures, in this process, when each colour image arrives: the error against the bag's
schedule (arrival − first arrival − bag offset, minus its median; both directions count). The
player's own figure (publish call − due time) is read from its output. Target: p95 ≤ 10 ms.
"""
from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

TUM = Path(__file__).resolve().parent.parent / "tests" / "data" / "rgbd"


# --quick (raspv_bench.bench_cli): a smoke run in seconds, run by tests/bench
QUICK = {"seconds": 2.0, "no_extra": True}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=10.0, help="length of the test bag [s] (default 10)")
    parser.add_argument("--rate", type=float, default=30.0, help="camera rate of the test bag [Hz] (default 30)")
    parser.add_argument("--bag", default=None, help="use this bag instead of the generated one")
    parser.add_argument("--device", default="default", help="device preset for part 1 (default: default)")
    parser.add_argument("--no-replay", action="store_true", help="skip part 2")
    parser.add_argument("--no-extra", action="store_true", help="part 1: only the default render")


def make_test_bag(path: Path, seconds: float, rate: float, storage: str = "mcap") -> int:
    """A 640×480 bag of the TUM desk frame drifting sideways and back (colour, depth, camera
    info), ``rate`` frames per second for ``seconds``. Returns the number of frames."""
    import cv2

    from raspv_bags.from_frames import CAMERA_PRESETS, RgbdBagWriter
    from raspv_common.intrinsics import CameraIntrinsics
    from raspv_common.rgbd_files import read_color, read_depth_scaled

    color = read_color(TUM / "tum_color.png")
    depth = read_depth_scaled(TUM / "tum_depth.png", 1.0 / 5000.0)
    fx, fy, cx, cy = CAMERA_PRESETS["primesense"]
    cam = CameraIntrinsics(640, 480, fx, fy, cx, cy)
    n = int(round(seconds * rate))
    t0 = 1.7e9
    with RgbdBagWriter(path, storage) as out:
        for i in range(n):
            dx = 20.0 * np.sin(2 * np.pi * i / max(n, 1))
            M = np.float32([[1, 0, dx], [0, 1, 0]])
            c = cv2.warpAffine(color, M, (640, 480), flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
            d = cv2.warpAffine(depth, M, (640, 480), flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
            out.add(t0 + i / rate, c, d, cam)
    return n


def _render(bag: Path, out: Path, **kw) -> tuple[float, int, float]:
    from raspv_bags.render import RenderSettings, render_bag

    rep = render_bag(bag, out, settings=RenderSettings(**kw))
    return rep.speed, rep.frames, rep.wall_s


def render_part(bag: Path, workdir: Path, device: str, extra: bool) -> dict:
    from raspv_bags.reader import BagReader
    from raspv_spv.config import spv_config
    from raspv_spv.simulator import PhospheneSimulator

    with BagReader(bag) as r:
        dur, n = r.duration_s, r.topics.get("/camera/color/image_raw")
    PhospheneSimulator(spv_config(device))  # computes the temporal look-up table once (cached on disk)
    load = os.getloadavg()[0]
    print(f"part 1 — offline render of {bag.name}: {dur:.1f} s, {n.count if n else 0} colour frames "
          f"(wall time includes opening the bag and building the simulator; load average {load:.1f} "
          f"on {os.cpu_count()} cores)")
    results = {}
    cases = [("default: grey, temporal, 800x800 @ 50 Hz, mp4", dict(spv={"device": device}))]
    if extra:
        cases += [("depth mode", dict(spv={"device": device, "mode": "depth"})),
                  ("side by side (colour | phosphenes)", dict(spv={"device": device}, side_by_side=True)),
                  ("without the temporal model", dict(spv={"device": device, "temporal": False}))]
    for i, (label, kw) in enumerate(cases):
        runs = [_render(bag, workdir / f"render{i}.mp4", **kw) for _ in range(3 if i == 0 else 1)]
        speed, frames, wall = sorted(runs)[len(runs) // 2]
        results[label] = speed
        spread = f"  (of 3: {min(r[0] for r in runs):.1f}-{max(r[0] for r in runs):.1f}x)" if len(runs) > 1 else ""
        print(f"  {label:44s} {frames:5d} frames in {wall:5.2f} s   {speed:5.1f}x real time{spread}")
    first = next(iter(results.values()))
    print(f"  target >= 5x real time (default preset, 30 Hz 640x480 source): {'met' if first >= 5 else 'NOT met'} "
          f"({first:.1f}x)")
    return results


def replay_part(bag: Path) -> dict:
    from raspv_bringup.testing import Probe, claim_private_domain
    from raspv_common import topics as T
    from raspv_common.qos import SENSOR_QOS
    from sensor_msgs.msg import Image

    from raspv_bags.reader import BagReader

    domain = claim_private_domain()
    with BagReader(bag) as r:
        bag_ts = [m.timestamp_ns for m in r.messages([T.COLOR])]
    probe = Probe("bench_bag")
    arrivals: list[float] = []
    sub = probe.node.create_subscription(Image, T.COLOR, lambda _raw: arrivals.append(time.monotonic()),
                                         SENSOR_QOS, raw=True)
    cmd = [sys.executable, "-m", "raspv_bringup.cli", "bag", "play", str(bag)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=os.environ.copy())
    try:
        out, _ = proc.communicate(timeout=120 + 3 * (bag_ts[-1] - bag_ts[0]) * 1e-9)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=30)
    probe.node.destroy_subscription(sub)
    probe.close()
    print(f"part 2 — replay of {bag.name} with `raspv bag play` (ROS domain {domain}), colour images timed "
          f"at a subscriber in another process")
    m = re.search(r"timing error over (\d+) messages: p50 ([\d.]+) ms, p95 ([\d.]+) ms, max ([\d.]+) ms", out)
    own = {}
    if m:
        own = {"p50": float(m.group(2)), "p95": float(m.group(3)), "max": float(m.group(4))}
        print(f"  player (publish call - due time), {m.group(1)} messages:  p50 {own['p50']:.2f} ms  "
              f"p95 {own['p95']:.2f} ms  max {own['max']:.2f} ms")
    else:
        print("  player output:\n" + out[-2000:])
    n = len(arrivals)
    if n < 2:
        print(f"  subscriber received {n} of {len(bag_ts)} colour images: no timing")
        return {"player": own}
    rel_arr = np.array(arrivals) - arrivals[0]
    rel_bag = (np.array(bag_ts[:n]) - bag_ts[0]) * 1e-9
    err = (rel_arr - rel_bag) * 1e3
    err -= np.median(err)
    a = np.abs(err)
    sub_stats = {"p50": float(np.percentile(a, 50)), "p95": float(np.percentile(a, 95)), "max": float(a.max())}
    print(f"  subscriber (arrival vs bag schedule), {n}/{len(bag_ts)} images:  p50 {sub_stats['p50']:.2f} ms  "
          f"p95 {sub_stats['p95']:.2f} ms  max {sub_stats['max']:.2f} ms")
    p95 = max(own.get("p95", 0.0), sub_stats["p95"])
    print(f"  target p95 <= 10 ms: {'met' if p95 <= 10 else 'NOT met'} ({p95:.2f} ms, the worse of the two)")
    return {"player": own, "subscriber": sub_stats}


def run(args: argparse.Namespace) -> int:
    with tempfile.TemporaryDirectory(prefix="raspv-bench-bag-") as tmp:
        workdir = Path(tmp)
        if args.bag:
            bag = Path(args.bag)
        else:
            bag = workdir / "bench_bag"
            t = time.monotonic()
            n = make_test_bag(bag, args.seconds, args.rate)
            size = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
            print(f"test bag: {n} frames 640x480 at {args.rate:g} Hz ({size:.0f} MB), written in "
                  f"{time.monotonic() - t:.1f} s")
        render_part(bag, workdir, args.device, not args.no_extra)
        if not args.no_replay:
            replay_part(bag)
    return 0
