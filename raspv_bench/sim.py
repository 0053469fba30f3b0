"""Virtual world speed: sim step + render + publish, and the rate a subscriber receives.

Part 1 times the core (no ROS) while the avatar drives through the world: physics/avatar step,
render (colour + depth + labels) and building the three image messages. Part 2 runs the real
``sim`` node in a graph (optionally with the other nodes of ``--graph FILE``, whose own RGB-D
source is replaced) on a private ROS domain, drives it with /cmd_vel, and measures from a subscriber in
another process the achieved colour rate, frame intervals and latency (stamp → receipt), each
node's CPU share, the sim's CPU time per frame (what the rate costs, whatever the load) and the
machine's load average meanwhile: on 2 cores the demo graph's nodes together ask for more than
the machine has, so the rate the sim holds there depends on the load (docs/sim.md). ``--quick``
(30 frames, 6 s) is what the test suite runs.
"""
from __future__ import annotations

import argparse
import math
import os
import re
import statistics
import tempfile
import time
from pathlib import Path

SOURCE_KINDS = {"sim", "synthetic", "camera", "replay"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--world", default=None, help="world name or file (default: --graph's sim world, else apartment)")
    parser.add_argument("--size", default=None, help="camera resolution WxH (default: --graph's sim size, else 320x240)")
    parser.add_argument("--margin", type=float, default=None,
                        help="field of view rendered around it [deg] (default: the sim node's margin_deg)")
    parser.add_argument("--renderer", choices=("auto", "egl", "tiny"), default="auto")
    parser.add_argument("--rate", type=float, default=None, help="node rate asked for [Hz] (default: --graph's sim rate, else 20)")
    parser.add_argument("--frames", type=int, default=200, help="frames timed in part 1 (default 200)")
    parser.add_argument("--seconds", type=float, default=15.0, help="measurement time of part 2 [s] (default 15)")
    parser.add_argument("--depth-noise", action="store_true", help="with the depth-sensor model on")
    parser.add_argument("--graph", metavar="FILE", help="also run this graph's other nodes during part 2 (its RGB-D source is "
                        "replaced by the benchmarked sim, configured as the graph's sim node unless given here)")
    parser.add_argument("--core-only", action="store_true", help="skip part 2 (no ROS)")
    parser.add_argument("--quick", action="store_true", help="30 frames in part 1 and 6 s in part 2 (the test suite's run)")


def _stats(values: list[float]) -> str:
    if not values:
        return "n/a"
    v = sorted(values)
    p95 = v[min(len(v) - 1, int(round(0.95 * (len(v) - 1))))]
    return f"median {statistics.median(v):6.1f}  p95 {p95:6.1f}  max {v[-1]:6.1f}"


def _size(text: str) -> tuple[int, int]:
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def _margin(args) -> float:
    if args.margin is not None:
        return args.margin
    from raspv_sim.sim_params import PARAMS
    return next(p.default for p in PARAMS if p.name == "margin_deg")


def _apply_graph_sim(args) -> None:
    """Fill the options not given from --graph's sim node (the graph's own world, size, margin
    and rate: `--graph config/demo.yaml` measures the demo's sim), else the defaults."""
    sim: dict = {}
    if args.graph:
        from raspv_bringup.graph import load_graph, resolve_graph_path

        graph = load_graph(resolve_graph_path(args.graph), check_files=False)
        sim = next((n.params for n in graph.nodes if n.kind == "sim"), {})
    if args.world is None:
        args.world = sim.get("world", "apartment")
    if args.size is None:
        args.size = f"{sim.get('width', 320)}x{sim.get('height', 240)}"
    if args.margin is None and "margin_deg" in sim:
        args.margin = float(sim["margin_deg"])
    if args.rate is None:
        args.rate = float(sim.get("rate", 20.0))


def core_bench(args) -> dict:
    import numpy as np

    from raspv_sim.depth_sensor import DepthSensorConfig
    from raspv_sim.simulator import SimConfig, Simulation

    width, height = _size(args.size)
    config = SimConfig(width=width, height=height, margin_deg=_margin(args), renderer=args.renderer,
                       depth_sensor=DepthSensorConfig() if args.depth_noise else None)
    step, render, convert = [], [], []
    try:
        from raspv_common.conversions import array_to_image
    except ImportError:  # no ROS message packages: time the byte copy the conversion does
        array_to_image = None
    with Simulation(args.world, config) as sim:
        renderer = sim.renderer.description
        cpu0 = time.process_time()
        for i in range(args.frames):
            t0 = time.perf_counter()
            sim.step(0.05, 0.8, 0.5 * math.sin(i / 15))
            t1 = time.perf_counter()
            frame = sim.render()
            t2 = time.perf_counter()
            if array_to_image is not None:
                array_to_image(frame.rgb, "rgb8")
                array_to_image(frame.depth, "32FC1")
                array_to_image(frame.labels, "mono8")
            else:
                for a in (frame.rgb, frame.depth, frame.labels):
                    np.ascontiguousarray(a).tobytes()
            t3 = time.perf_counter()
            step.append(1e3 * (t1 - t0))
            render.append(1e3 * (t2 - t1))
            convert.append(1e3 * (t3 - t2))
        cpu_ms = 1e3 * (time.process_time() - cpu0) / args.frames
        collisions = sim.monitor.count
        shadow_peer = _shadow_pass_peer(sim, args.frames)
    total = [a + b + c for a, b, c in zip(step, render, convert)]
    K = config.intrinsics()
    print(f"part 1 — core, {args.world} at {width}x{height} + {_margin(args):g}° margin = {K.width}x{K.height}, "
          f"{args.frames} frames, renderer {renderer}"
          f"{', depth noise on' if args.depth_noise else ''} ({collisions} collisions on the way)")
    print(f"  step (people + avatar)   [ms] {_stats(step)}")
    print(f"  render (RGB-D + labels)  [ms] {_stats(render)}")
    print(f"  image messages           [ms] {_stats(convert)}")
    print(f"  total                    [ms] {_stats(total)}  → {1e3 / statistics.median(total):.0f} fps possible")
    print(f"  CPU per frame            [ms] {cpu_ms:6.1f}  → {1e3 / cpu_ms:.0f} fps on one whole core")
    if shadow_peer is not None:
        print(f"  peer: PyBullet's EGL with its shadow-map pass (ignores shadow=0): CPU per render "
              f"{shadow_peer[1]:.1f} ms vs {shadow_peer[0]:.1f} ms without it ({shadow_peer[1] / shadow_peer[0]:.1f}x)")
    return {"total_ms": statistics.median(total), "cpu_ms": cpu_ms}


def _shadow_pass_peer(sim, frames: int) -> tuple[float, float] | None:
    """(CPU ms per render without, with) the EGL plugin's shadow-map pass, side by side on the
    same view (:mod:`raspv_sim.egl_shadow_pass`); None with TinyRenderer or a plugin left as is."""
    import importlib.util

    from raspv_sim.egl_shadow_pass import set_shadow_map

    if sim.renderer.name != "egl":
        return None
    plugin = importlib.util.find_spec("eglRenderer").origin
    out = []
    try:
        for on in (False, True):
            if set_shadow_map(plugin, on) is not None:
                return None
            sim.render()
            cpu0 = time.process_time()
            for _ in range(max(3, frames // 4)):
                sim.render()
            out.append(1e3 * (time.process_time() - cpu0) / max(3, frames // 4))
    finally:
        set_shadow_map(plugin, False)
    return out[0], out[1]


def node_bench(args) -> int:
    import yaml
    from geometry_msgs.msg import Twist
    from sensor_msgs.msg import Image

    from raspv_bringup.testing import Probe, RunningGraph, claim_private_domain
    from raspv_common import topics
    from raspv_common.conversions import stamp_to_seconds

    domain = claim_private_domain()
    width, height = _size(args.size)
    graph: dict = {"launch": {"nodes": [{"kind": "sim", "name": "sim"}]}}
    others = []
    if args.graph:
        from raspv_bringup.graph import resolve_graph_path

        extra = yaml.safe_load(resolve_graph_path(args.graph).read_text()) or {}
        for node in (extra.get("launch") or {}).get("nodes", []):
            if node.get("kind") in SOURCE_KINDS:     # the benchmarked sim node is the source
                continue
            name = node.get("name", node.get("kind"))
            graph["launch"]["nodes"].append(node)
            others.append(name)
            if name in extra:
                graph[name] = extra[name]
        if (extra.get("launch") or {}).get("env"):
            graph["launch"]["env"] = extra["launch"]["env"]
    graph["sim"] = {"ros__parameters": {"world": args.world, "width": width, "height": height, "rate": args.rate,
                                        "margin_deg": _margin(args),
                                        "renderer": args.renderer, "depth_noise": bool(args.depth_noise),
                                        "cmd_timeout": 1.0}}
    workdir = Path(tempfile.mkdtemp(prefix="raspv-bench-sim-"))
    g = RunningGraph(graph, workdir)
    probe = Probe("bench_sim")
    arrivals: list[float] = []
    latencies: list[float] = []
    cpu_before = cpu_after = {}
    try:
        g.wait_for_output(r"renderer: ", timeout=60)
        col = probe.subscribe(topics.COLOR, Image)
        col.wait(3, timeout=60)
        pub = probe.publisher(topics.CMD_VEL, Twist, wait_for_subscribers=1)
        col.messages.clear()
        col.stamps.clear()
        cpu_before, machine_before = g.cpu_by_kind(), g.machine_ticks()
        start = time.monotonic()
        k = 0
        while time.monotonic() - start < args.seconds:
            twist = Twist()
            twist.linear.x, twist.angular.z = 0.8, 0.5 * math.sin(k / 15)
            pub.publish(twist)
            k += 1
            time.sleep(0.1)
        with col._cond:
            msgs, stamps = list(col.messages), list(col.stamps)
        elapsed = time.monotonic() - start
        cpu_after, machine_after, load = g.cpu_by_kind(), g.machine_ticks(), os.getloadavg()
        wall_now = time.time() - time.monotonic()
        for m, t in zip(msgs, stamps):
            latencies.append(1e3 * ((t + wall_now) - stamp_to_seconds(m.header.stamp)))
        arrivals = [1e3 * (b - a) for a, b in zip(stamps, stamps[1:])]
        probe.unsubscribe(col)
    finally:
        probe.close()
        g.stop()
    m = re.search(r"sim: (\d+) frames; mean step ([\d.]+) ms, render ([\d.]+) ms, publish ([\d.]+) ms", g.output)
    rate = len(msgs) / elapsed if elapsed > 0 else 0.0
    print(f"part 2 — sim node in a graph (ROS domain {domain}{', with ' + ', '.join(others) if others else ''}), "
          f"asked {args.rate:g} Hz, {args.seconds:g} s while driving")
    if m:
        print(f"  node: {m.group(1)} frames, mean step {m.group(2)} ms, render {m.group(3)} ms, publish {m.group(4)} ms")
    print(f"  received colour frames: {len(msgs)} → {rate:.1f} Hz achieved, load average {load[0]:.1f} "
          f"({g.machine_share(machine_before, machine_after)})")
    print(f"  CPU of the nodes (% of one core): {g.cpu_share(cpu_before, cpu_after, elapsed)}")
    if "sim" in cpu_before and "sim" in cpu_after and msgs:
        sim_cpu_ms = 1e3 * (cpu_after["sim"][1] - cpu_before["sim"][1]) / len(msgs)
        print(f"  sim CPU per frame        [ms] {sim_cpu_ms:6.1f}  → {args.rate:g} Hz needs "
              f"{sim_cpu_ms * args.rate / 10:.0f} % of a core")
    print(f"  frame interval           [ms] {_stats(arrivals)}")
    print(f"  latency stamp → receipt  [ms] {_stats(latencies)}")
    ok = rate >= 0.95 * args.rate
    print(f"  {'OK' if ok else 'BELOW TARGET'}: {rate:.1f} Hz {'≥' if ok else '<'} 95 % of {args.rate:g} Hz")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.quick:
        args.frames, args.seconds = min(args.frames, 30), min(args.seconds, 6.0)
    try:
        _apply_graph_sim(args)
    except Exception as exc:  # noqa: BLE001 - GraphError and file errors: one line
        print(f"raspv bench sim: {str(exc).splitlines()[0]}")
        return 2
    try:
        _size(args.size)
    except ValueError:
        print(f"raspv bench sim: --size must be WxH, e.g. 320x240, got {args.size!r}")
        return 2
    core_bench(args)
    if not args.core_only:
        return node_bench(args)
    return 0
