"""Live views in the demo graph: CPU of the foxglove and viz nodes while a Foxglove client watches the shipped layout's topics, and the phosphene display rate with them and without them.

The demo graph (sim, scene, spv, bridge) runs once plain and once with ``viz`` and ``foxglove``
added; a Foxglove client (raspv_viz/foxglove_client.py, in this process) subscribes to every
topic of config/foxglove_layout.json the graph has. Figures: each node's CPU in % of one core
over the window (target for foxglove: ≤ 10 %), what the client received per topic, and
/spv/image at a ROS subscriber per second in both runs (the display rate, 50 Hz configured).
"""
from __future__ import annotations

import argparse
import re
import tempfile
import time
from pathlib import Path

from raspv_common import topics

LAYOUT_TOPICS = [topics.SPV_IMAGE, topics.COLOR, topics.VIZ_SCENE, topics.VIZ_STAIRS, topics.VIZ_PATH,
                 topics.VIZ_PHOSPHENES, topics.VIZ_CLOUD, topics.NAV_COSTMAP, "/raspv/latency", "/sysinfo"]
# the layout topics the demo graph with viz publishes (no planner: no path, no costmap; stairs only near stairs)
DEMO_VIEW_TOPICS = {topics.SPV_IMAGE, topics.COLOR, topics.VIZ_SCENE, topics.VIZ_PHOSPHENES, topics.VIZ_CLOUD,
                    "/raspv/latency", "/sysinfo"}
URL = r"Foxglove: open connection → Foxglove WebSocket → (ws://\S+)"
FOXGLOVE_SUMMARY = r"foxglove: (\d+) messages \((\d+) MB\) sent on (\d+) channels in (\d+) s, CPU ([\d.]+) s"


class GraphFailed(RuntimeError):
    pass


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=30.0, help="measurement window of each run [s] (default 30)")
    parser.add_argument("--warmup", type=float, default=8.0, help="time after the first phosphene image before "
                        "measuring [s] (default 8)")
    parser.add_argument("--quick", action="store_true",
                        help="only the run with the live views, 4 s after 3 s of warm-up (tests)")
    parser.add_argument("--max-rate", type=float, default=0.0, metavar="HZ",
                        help="the foxglove node's max_rate (default 0: every message)")


def demo_spec(with_views: bool, max_rate: float = 0.0) -> dict:
    import yaml

    from raspv_bringup.graph import CONFIG_DIR

    spec = yaml.safe_load((CONFIG_DIR / "demo.yaml").read_text())
    spec.setdefault("bridge", {"ros__parameters": {}})["ros__parameters"].update({"port": 0, "tcp_port": -1})
    if with_views:
        spec["launch"]["nodes"] += [{"kind": "viz"}, {"kind": "foxglove"}]
        spec["foxglove"] = {"ros__parameters": {"port": 0, "max_rate": float(max_rate)}}
    return spec


def measure(with_views: bool, seconds: float, warmup: float, workdir: Path, max_rate: float = 0.0) -> dict:
    """One run: {"cpu": {kind: % of a core}, "display_hz", "client_hz": {topic: Hz}, "machine",
    "shown": share of the spv node's display ticks it showed (its exit line), "sent": the foxglove
    node's exit line (messages, MB, channels, s, CPU s) or None}."""
    from sensor_msgs.msg import Image

    from raspv_bringup.testing import Probe, RunningGraph
    from raspv_common.qos import SENSOR_QOS
    from raspv_viz.foxglove_client import FoxgloveClient

    workdir.mkdir(parents=True, exist_ok=True)
    graph = RunningGraph(demo_spec(with_views, max_rate), workdir)
    probe = Probe("foxglove_bench")
    arrivals: list[float] = []
    client = None
    try:
        probe.node.create_subscription(Image, topics.SPV_IMAGE, lambda _raw: arrivals.append(time.monotonic()),
                                       SENSOR_QOS, raw=True)
        deadline = time.monotonic() + 180
        while not arrivals:
            if not graph.running() or time.monotonic() > deadline:
                raise GraphFailed(graph.output[-2000:])
            time.sleep(0.2)
        if with_views:
            client = FoxgloveClient(graph.wait_for_output(URL, timeout=60).group(1))
            client.keep = False
            # every layout topic the demo graph with views publishes (a viz topic appears only with
            # its first message: subscribing to whatever was there after 3 s measured 60 messages/s
            # in one run and 156 in the next)
            deadline = time.monotonic() + 60
            while not DEMO_VIEW_TOPICS <= set(client.channels) and time.monotonic() < deadline:
                client.pump(0.5)
            client.subscribe([t for t in LAYOUT_TOPICS if t in client.channels])
        _wait(client, warmup)
        cpu0, ticks0, t0 = graph.cpu_by_kind(), graph.machine_ticks(), time.monotonic()
        counts0 = dict(client.counts) if client else {}
        n0 = len(arrivals)
        _wait(client, seconds)
        wall = time.monotonic() - t0
        cpu1, ticks1 = graph.cpu_by_kind(), graph.machine_ticks()
        if not graph.running():
            raise GraphFailed(graph.output[-2000:])
        result = {
            "cpu": {k: 100.0 * (t - cpu0[k][1]) / wall for k, (pid, t) in cpu1.items() if k in cpu0 and cpu0[k][0] == pid},
            "display_hz": (len(arrivals) - n0) / wall,
            "client_hz": {t: (c - counts0.get(t, 0)) / wall for t, c in sorted(client.counts.items())} if client else {},
            "machine": RunningGraph.machine_share(ticks0, ticks1),
        }
    finally:
        if client is not None:
            client.close()
        probe.close()
        graph.stop()
    shown = graph.spv_display()
    result["shown"] = shown[0] / max(1, sum(shown)) if shown else None
    sent = re.search(FOXGLOVE_SUMMARY, graph.output)
    result["sent"] = tuple(float(v) for v in sent.groups()) if sent else None
    return result


def _wait(client, seconds: float) -> None:
    """Let ``seconds`` pass, reading the client's frames meanwhile (a client that stops reading
    is one the server drops messages for)."""
    if client is None:
        time.sleep(seconds)
    else:
        client.pump(seconds)


def run(args: argparse.Namespace) -> int:
    from raspv_bringup.testing import claim_private_domain

    claim_private_domain()                 # its graphs never meet another run's (it used the caller's domain)
    seconds = 4.0 if args.quick else args.seconds
    warmup = min(args.warmup, 3.0) if args.quick else args.warmup
    runs = [True] if args.quick else [False, True]
    results = {}
    with tempfile.TemporaryDirectory(prefix="raspv-bench-foxglove-") as tmp:
        for with_views in runs:
            label = "with viz + foxglove" if with_views else "plain demo graph"
            print(f"raspv bench foxglove: {label}, {seconds:.0f} s after {warmup:.0f} s of warm-up ...", flush=True)
            try:
                results[with_views] = r = measure(with_views, seconds, warmup, Path(tmp) / label.replace(" ", "_"),
                                                  args.max_rate)
            except (GraphFailed, TimeoutError) as exc:
                print(f"raspv bench foxglove: the graph failed: {exc}")
                return 1
            cpu = ", ".join(f"{k} {v:.1f} %" for k, v in sorted(r["cpu"].items()))
            print(f"  CPU of one core: {cpu}; {r['machine']}")
            print(f"  /spv/image at a ROS subscriber: {r['display_hz']:.1f} Hz"
                  + (f"; the spv node showed {100 * r['shown']:.1f} % of its 50 Hz display ticks" if r["shown"] else ""))
            if r["sent"]:
                n, mb, channels, s, cpu = r["sent"]
                print(f"  foxglove node over its life: {n:.0f} messages ({mb:.0f} MB) sent on {channels:.0f} channels in "
                      f"{s:.0f} s, {1000 * cpu / max(n, 1):.2f} ms of CPU per message sent")
            if r["client_hz"]:
                print("  Foxglove client received: " + ", ".join(f"{t} {hz:.1f} Hz" for t, hz in r["client_hz"].items()))
    on = results[True]
    print(f"foxglove node (max_rate {args.max_rate:g} Hz): {on['cpu'].get('foxglove', float('nan')):.1f} % of one core "
          f"(target ≤ 10 %), "
          f"viz node: {on['cpu'].get('viz', float('nan')):.1f} %")
    if False in results:
        off = results[False]
        print(f"display rate: {on['display_hz']:.1f} Hz with the live views, {off['display_hz']:.1f} Hz without "
              f"({on['display_hz'] / max(off['display_hz'], 1e-9):.3f}×) at a ROS subscriber in this process"
              + (f"; the spv node showed {100 * on['shown']:.1f} % vs {100 * off['shown']:.1f} % of its display ticks"
                 if on["shown"] is not None and off["shown"] is not None else ""))
    return 0
