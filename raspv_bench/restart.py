"""Node restarts: `kill -9` a node marked ``restart: true`` and time how long until it is back.

A graph (synthetic RGB-D source → scene → spv in a scene mode, every node ``restart: true``)
runs on a private ROS domain. For each victim (``scene``, ``spv``) and repetition the node's
process is killed with SIGKILL, and a probe measures from the kill to

- the first message the new process publishes (``/scene/structure``; ``/spv/frame``),
- the first phosphene frame computed from input newer than the kill (for ``scene``: how long
  the wearer's image was built from a dead scene node — part B of issue 16 bounds that),

and the new process reports when its start-up stages ended (``RASPV_STARTUP_REPORT``):
interpreter ready, imports done, rclpy initialised, node built. Figures under load are noisy.
"""
from __future__ import annotations

import argparse
import os
import re
import signal
import statistics
import tempfile
import time
from pathlib import Path

STAGES = ("interpreter ready", "imports done", "rclpy initialised", "node built")


# --quick (raspv_bench.bench_cli): a smoke run in seconds, run by tests/bench
QUICK = {"repeat": 1, "nodes": "spv"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--repeat", type=int, default=3, help="kills per node and mode (default 3)")
    parser.add_argument("--nodes", default="scene,spv", help="nodes to kill, comma-separated (default scene,spv)")
    parser.add_argument("--modes", default="cold,spare",
                        help="restart modes to compare: cold (new process), spare (warm spare); default both")
    parser.add_argument("--timeout", type=float, default=60.0, help="give up on a restart after this [s]")


def graph_spec(spare: bool) -> dict:
    nodes = [{"kind": k, "restart": True, "spare": spare} for k in ("synthetic", "scene", "spv")]
    return {"launch": {"nodes": nodes, "env": {"RASPV_STARTUP_REPORT": "1"}},
            "synthetic": {"ros__parameters": {"rate": 20.0}},
            "spv": {"ros__parameters": {"device": "optimist", "mode": "chess_wall_obstacles"}}}


def _stages(text: str, name: str) -> dict[str, float]:
    out = {}
    for m in re.finditer(rf"^\[{name}\] startup: (.+?) at ([\d.]+) s$", text, re.M):
        out[m.group(1)] = float(m.group(2))
    return out


def _median(values: list[float]) -> str:
    return f"{statistics.median(values):5.2f}" if values else "  n/a"


def run(args: argparse.Namespace) -> int:
    from raspv_bringup.testing import Probe, claim_private_domain

    domain = claim_private_domain()
    victims = [v.strip() for v in args.nodes.split(",") if v.strip()]
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    print(f"raspv bench restart (domain {domain}): synthetic 320x240 20 Hz → scene → spv (optimist, "
          f"chess_wall_obstacles, 50 Hz), every node restart: true; SIGKILL {args.repeat} times per node")
    probe = Probe("bench_restart")
    try:
        results = {mode: _measure(probe, victims, mode == "spare", args) for mode in modes}
    finally:
        probe.close()
    print("  median seconds after the kill (start-up stages: after the spawn or the spare's promotion, "
          "which follow the kill within ~1 ms)")
    print(f"  {'node':<8} {'restart':<7} {'interp.':>7} {'imports':>7} {'rclpy':>7} {'built':>7} {'1st msg':>8} "
          f"{'1st image of new input':>23}")
    for mode, rows in results.items():
        for name, r in rows.items():
            print(f"  {name:<8} {mode:<7} {_median(r['interpreter ready']):>7} {_median(r['imports done']):>7} "
                  f"{_median(r['rclpy initialised']):>7} {_median(r['node built']):>7} {_median(r['first message']):>8} "
                  f"{_median(r['first content']):>23}   (max 1st msg {max(r['first message'], default=0):.2f} s, "
                  f"{r['spare used']} of {len(r['first message'])} from a spare)")
    return 0


def _measure(probe, victims: list[str], spare: bool, args) -> dict[str, dict]:
    from raspv_bringup.testing import RunningGraph
    from raspv_common import topics
    from raspv_msgs.msg import PhospheneFrame, SceneStructure

    g = RunningGraph(graph_spec(spare), Path(tempfile.mkdtemp(prefix="raspv-bench-restart-")))
    rows: dict[str, dict] = {}
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    scene = probe.subscribe(topics.SCENE_STRUCTURE, SceneStructure)
    try:
        frames.wait(1, timeout=args.timeout, predicate=lambda m: _stamp(m.source_stamp) > 0)
        for name in victims:
            r = rows.setdefault(name, {k: [] for k in ("first message", "first content", *STAGES)})
            r["spare used"] = 0
            for k in range(args.repeat):
                if spare:       # the node's own imports, then one spare per kill so far, then this one's
                    g.wait_for_lines(rf"^\[{name}\] startup: imports done", 2 + k, args.timeout)
                else:
                    time.sleep(2.0)
                out_len = len(g.output)
                pid = g.pid_of(name)
                t_kill = time.time()
                os.kill(pid, signal.SIGKILL)
                col = scene if name == "scene" else frames
                after = (lambda m: _stamp(m.header.stamp) > t_kill)
                col.wait(1, timeout=args.timeout, predicate=after)
                first = next(t for m, t in zip(list(col.messages), list(col.stamps)) if after(m))
                content = frames.wait(1, timeout=args.timeout, predicate=lambda m: _stamp(m.source_stamp) > t_kill)[0]
                t_content = next(t for m, t in zip(list(frames.messages), list(frames.stamps)) if m is content)
                offset = time.time() - time.monotonic()
                r["first message"].append(first + offset - t_kill)
                r["first content"].append(t_content + offset - t_kill)
                g.wait_for_output(rf"\[{name}\] startup: node built", timeout=args.timeout)
                text = g.output[out_len:]
                r["spare used"] += "warm spare" in text
                stages = _stages(text, name)
                for stage in STAGES:
                    if stage in stages:
                        r[stage].append(stages[stage])
                for c in (frames, scene):
                    with c._cond:
                        c.messages.clear()
                        c.stamps.clear()
    finally:
        probe.unsubscribe(frames)
        probe.unsubscribe(scene)
        g.stop()
    return rows


def _stamp(t) -> float:
    return t.sec + 1e-9 * t.nanosec
