"""Soak: run a graph for N minutes and report memory growth per node, dropped display frames and restarts.

The graph (``demo`` by default) runs under the launcher's supervisor in this process, on a
private ROS domain. Every ``--interval`` seconds each node's resident memory is sampled
(``psutil``; a warm spare is its own row); at the end each node's growth is a straight-line fit
after a warm-up (:mod:`raspv_bench.soak_figures`), in MB/hour with its standard error. Display frames:
the spv node's own count of late ticks (its log), and the gaps between ``/spv/frame`` stamps
seen by a subscriber here. Target (issue 16): growth ≤ 1 MB/hour per node over 30 minutes.
Figures under load are noisy; a short soak's slope has a large standard error.
"""
from __future__ import annotations

import argparse
import csv
import math
import re
import sys
import tempfile
import threading
import time
from pathlib import Path

GROWTH_TARGET_MB_H = 1.0


# --quick (raspv_bench.bench_cli): a smoke run in seconds, run by tests/bench
QUICK = {"minutes": 0.25, "interval": 2.0, "warmup": 4.0}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--minutes", type=float, default=5.0, help="how long to run (default 5)")
    parser.add_argument("--graph", default="demo", help="graph file or name in config/ (default demo)")
    parser.add_argument("--interval", type=float, default=5.0, help="seconds between memory samples (default 5)")
    parser.add_argument("--warmup", type=float, default=None, metavar="S",
                        help="seconds of each process left out of the growth fit (default: 20%% of the run, at most 120)")
    parser.add_argument("--csv", metavar="FILE", help="write every memory sample (node, pid, t, RSS MB)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="NODE.PARAM:=VALUE",
                        help="override a parameter (repeatable); a bridge gets free ports unless set")


def run(args: argparse.Namespace) -> int:
    import psutil

    from raspv_bringup.graph import GraphError, load_graph, resolve_graph_path
    from raspv_bench.soak_figures import RssSeries, display_gaps, proc_memory
    from raspv_bringup.supervisor import Supervisor
    from raspv_bringup.testing import Probe, claim_private_domain

    domain = claim_private_domain()
    path = resolve_graph_path(args.graph)
    overrides = list(args.overrides)
    try:
        graph = load_graph(path, overrides)
        for n in graph.nodes:                  # never take the ports of a bridge the user runs
            if n.kind == "bridge":
                given = {o.split(":=")[0] for o in overrides}
                overrides += [o for o in (f"{n.name}.port:=0", f"{n.name}.tcp_port:=-1") if o.split(":=")[0] not in given]
        graph = load_graph(path, overrides)
    except GraphError as exc:
        for line in exc.errors:
            print(f"raspv bench soak: {line}", file=sys.stderr)
        return 2
    work = Path(tempfile.mkdtemp(prefix="raspv-bench-soak-"))
    log_path = work / "launch.log"
    duration = 60.0 * args.minutes
    warmup = args.warmup if args.warmup is not None else min(120.0, 0.2 * duration)
    print(f"raspv bench soak (domain {domain}): {path} for {args.minutes:g} min, memory every {args.interval:g} s, "
          f"growth fitted after {warmup:.0f} s of each process; launcher output in {log_path}", flush=True)

    with open(log_path, "w") as out:
        sup = Supervisor(graph, out=out, log_dir=work / "nodes")
        stop = threading.Event()
        sup.start()
        runner = threading.Thread(target=sup.run, kwargs={"should_continue": lambda: not stop.is_set()}, daemon=True)
        runner.start()
        probe = Probe("bench_soak")
        stamps: list[float] = []
        rate = next((float(n.params.get("rate", 50.0)) for n in graph.nodes if n.kind == "spv"), None)
        if rate is not None:
            from raspv_common import topics
            from raspv_msgs.msg import PhospheneFrame
            from rclpy.qos import QoSProfile, ReliabilityPolicy

            probe.node.create_subscription(
                PhospheneFrame, topics.SPV_FRAME,
                lambda m: stamps.append(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec),
                QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE))
        series: dict[str, RssSeries] = {}
        rows: list[tuple[str, int, float, float]] = []
        t0 = time.monotonic()
        next_report = 60.0
        try:
            while (t := time.monotonic() - t0) < duration and runner.is_alive():
                for node in sup.nodes:
                    procs = [(node.entry.name, node.proc)]
                    if node.spare is not None:
                        procs.append((f"{node.entry.name} (spare)", node.spare.proc))
                    for name, proc in procs:
                        if proc is None or proc.returncode is not None:
                            continue
                        try:
                            rss = psutil.Process(proc.pid).memory_info().rss
                            kinds = proc_memory(proc.pid)
                        except (psutil.Error, OSError):
                            continue
                        series.setdefault(name, RssSeries(name)).add(proc.pid, t, rss)
                        for kind in ("anon", "shmem"):
                            series.setdefault(f"{name}/{kind}", RssSeries(name)).add(proc.pid, t, kinds.get(kind, 0))
                        rows.append((name, proc.pid, t, rss / 1e6, kinds.get("anon", 0) / 1e6, kinds.get("shmem", 0) / 1e6))
                if t >= next_report:
                    total = sum(s.segments[-1][2][-1] for k, s in series.items() if s.segments and "/" not in k)
                    frames = f", {len(stamps)} display frames received" if rate is not None else ""
                    print(f"  {t / 60:5.1f} min: {total:.0f} MB in all{frames}", flush=True)
                    next_report += 60.0
                time.sleep(max(0.0, args.interval - ((time.monotonic() - t0) - t)))
        finally:
            stop.set()
            runner.join(timeout=60)
            probe.close()
    text = log_path.read_text(errors="replace")
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["node", "pid", "t_s", "rss_mb", "anon_mb", "shmem_mb"])
            w.writerows(rows)
    print("  growth: MB/hour of resident memory, ± its standard error; heap = private memory (what a leak grows); shared "
          "mem. = pages of the DDS shared-memory segments this process touched — its own and those of the nodes it "
          "reads, each at most 16 MB (config/fastdds_shm.xml), so that part stops growing once they are all touched")

    print(f"  {'node':<18} {'restarts':>8} {'RSS first':>10} {'last':>8} {'growth MB/h':>16} {'of which heap':>14} "
          f"{'shared mem.':>12} {'2nd half MB/h':>16} {'fit over':>9}  target ≤ {GROWTH_TARGET_MB_H:g} MB/h")
    worst = 0.0
    for node in sup.nodes:
        for name in (node.entry.name, f"{node.entry.name} (spare)"):
            s = series.get(name)
            if s is None:
                continue
            g = s.growth(warmup)
            restarts = node.restart_count if name == node.entry.name else s.restarts
            if g is None:
                print(f"  {name:<18} {restarts:>8}   (too few samples after the warm-up)")
                continue
            heap, shm = (series.get(f"{name}/{k}") for k in ("anon", "shmem"))
            heap_g, shm_g = (x.growth(warmup) if x is not None else None for x in (heap, shm))
            heap_late = heap_g.late_slope_mb_h - 2 * heap_g.late_stderr_mb_h if heap_g is not None else math.inf
            heap_all = heap_g.slope_mb_h - 2 * heap_g.stderr_mb_h if heap_g is not None else math.inf
            if name == node.entry.name and heap_g is not None:
                worst = max(worst, heap_g.late_slope_mb_h)
            ok = ("ok" if g.slope_mb_h - 2 * g.stderr_mb_h <= GROWTH_TARGET_MB_H else
                  "levels off" if g.late_slope_mb_h - 2 * g.late_stderr_mb_h <= GROWTH_TARGET_MB_H else
                  "heap ok, shared mem. fills" if min(heap_all, heap_late) <= GROWTH_TARGET_MB_H else "ABOVE")
            parts = " ".join(f"{x.slope_mb_h:>+12.2f}" if x is not None else f"{'?':>12}" for x in (heap_g, shm_g))
            print(f"  {name:<18} {restarts:>8} {g.first_mb:>8.0f}MB {g.last_mb:>6.0f}MB {g.slope_mb_h:>+8.2f} ± {g.stderr_mb_h:<5.2f} "
                  f"{parts} {g.late_slope_mb_h:>+8.2f} ± {g.late_stderr_mb_h:<5.2f} {g.span_s / 60:>7.1f}m  {ok}")
    if rate is not None:
        own = sum(int(m) for m in re.findall(r"^\[\w+\] \[WARN\].*dropped (\d+) display frames", text, re.M))
        final = re.findall(r"spv: (\d+) display frames, (\d+) dropped", text)
        shown, dropped = (int(final[-1][0]), int(final[-1][1])) if final else (None, own)
        gaps = display_gaps(stamps, rate)
        share = f" ({100.0 * dropped / max(1, shown + dropped):.2f} %)" if shown is not None else ""
        print(f"  display at {rate:g} Hz: the spv node dropped {dropped} frames{share}"
              + (f" of {shown + dropped}" if shown is not None else "")
              + f"; a subscriber here received {len(stamps)} frames with {gaps} missing between their stamps")
    restarts = [f"{n.entry.name} {n.restart_count} ({n.last_restart_reason})" for n in sup.nodes if n.restart_count]
    print(f"  restarts: {', '.join(restarts) if restarts else 'none'}")
    print(f"  largest heap growth of a node over the second half {worst:+.2f} MB/h (target ≤ {GROWTH_TARGET_MB_H:g} MB/h "
          "over a 30-minute soak)")
    return 0
