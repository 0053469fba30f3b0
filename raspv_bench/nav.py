"""Navigation speed: A* replanning against the previous Dijkstra, costmap update, DWA, the graph.

Part 1 times the cores (no ROS) on the office's structural map (420×260 cells at 5 cm):

- global replanning from 8 places along the route to the bin, with nobody about and with a
  person (a 0.5 m disc on the live layer) 2 m ahead in the corridor: this A*
  (``GlobalPlanner.plan``: relocation, the static path reused when the live layer leaves it
  alone, else A* on reduced costs; smoothing included), against the *previous* planner of this
  project (the whole graph rebuilt with the live obstacles, then a full scipy Dijkstra — kept
  here as the peer), and a textbook heapq A* with an octile heuristic (same graph);
- the costmap update from one 640×480 depth frame (marking, ray-cast clearing, inflation);
- one DWA step (189 commands rolled out over 2 s, clearance from the costmap).

Part 2 runs ``config/navigation.yaml`` on a private ROS domain with a scripted subject that
follows ``/nav/cmd_vel_hint``, and reports the phosphene display's rate and dropped frames
(the spv node's count) and the planner node's own timings.
"""
from __future__ import annotations

import argparse
import re
import statistics
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


# --quick (raspv_bench.bench_cli): a smoke run in seconds, run by tests/bench
QUICK = {"repeats": 2, "seconds": 5.0}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats of each replan (default 5)")
    parser.add_argument("--seconds", type=float, default=30.0, help="measurement time of part 2 [s] (default 30)")
    parser.add_argument("--core-only", action="store_true", help="skip part 2 (no ROS)")


def _stats(values: list[float]) -> str:
    if not values:
        return "n/a"
    v = sorted(values)
    p95 = v[min(len(v) - 1, int(round(0.95 * (len(v) - 1))))]
    return f"median {statistics.median(v):7.2f}  p95 {p95:7.2f}  max {v[-1]:7.2f}"


def _time(fn, repeats: int, cpu: list[float] | None = None) -> list[float]:
    """Wall milliseconds of ``repeats`` calls; their CPU milliseconds (this thread's) appended
    to ``cpu`` when given (the ratios: what other processes' load does not change)."""
    out = []
    for _ in range(repeats):
        c0, t0 = time.thread_time(), time.perf_counter()
        fn()
        out.append(1e3 * (time.perf_counter() - t0))
        if cpu is not None:
            cpu.append(1e3 * (time.thread_time() - c0))
    return out


def previous_replan(grid, config, live_obstacles, start, goal, planner):
    """The planner this project had before: the whole graph rebuilt from the map and the live
    obstacles at every replan, then one full Dijkstra from the start (scipy), then smoothing."""
    import numpy as np
    from scipy.sparse.csgraph import dijkstra

    from raspv_nav.astar import grid_graph
    from raspv_nav.costmap import inflate_obstacles

    state = inflate_obstacles(live_obstacles, grid.resolution, config)
    graph = grid_graph(state.cell_cost, grid.resolution)
    cols = grid.shape[1]
    s = planner.cell_of(start, "start")
    g = planner.cell_of(goal, "goal")
    s, g = s[0] * cols + s[1], g[0] * cols + g[1]
    _, pred = dijkstra(graph, directed=True, indices=s, return_predecessors=True)
    chain = [g]
    while chain[-1] != s:
        chain.append(int(pred[chain[-1]]))
    cells = np.column_stack(np.divmod(np.asarray(chain[::-1]), cols))
    return grid.cell_to_world(cells[planner._shortcut(cells, state)])


def core_bench(args) -> dict[str, float]:
    """Part 1, printed; the ratios against the peers timed beside ours at every start:
    ``previous_dijkstra`` (with a person ahead) and ``textbook_astar`` (times faster)."""
    import numpy as np

    from raspv_nav.assistant import NavigationAssistant
    from raspv_nav.astar import astar_reference, blocked_border
    from raspv_nav.costmap import inflate_obstacles
    from raspv_nav.motion import planar_pose
    from raspv_sim.occupancy_export import world_occupancy
    from raspv_sim.simulator import SimConfig, Simulation

    with Simulation("office", SimConfig(width=640, height=480)) as sim:
        grid = world_occupancy(sim.world, 0.05, structure_only=True)
        goal = np.array(sim.spec.goals[0].position)
        frame = sim.render()                                  # the spawn's view: the corridor, the walker
    assistant = NavigationAssistant(grid, goal)
    planner, costmap = assistant.planner, assistant.costmap
    t0 = time.perf_counter()
    planner.plan((1.0, 6.0), goal)
    first = 1e3 * (time.perf_counter() - t0)
    starts = [(1.0, 6.0), (3.0, 6.0), (5.0, 6.1), (7.0, 5.9), (9.0, 6.0), (11.0, 6.0), (12.5, 6.0), (13.5, 6.2)]
    rows, cols = grid.shape
    rr, cc = np.mgrid[:rows, :cols]
    new_free, new_person, old_person, heap_person, expanded = [], [], [], [], []
    cpu: dict[str, list[float]] = {"new": [], "old": [], "heap": []}
    for start in starts:
        new_free += _time(lambda: planner.plan(start, goal), args.repeats)
        person = grid.world_to_cell([[start[0] + 2.0, 6.0]])[0]
        live = costmap.static_obstacles | ((rr - person[0]) ** 2 + (cc - person[1]) ** 2 <= 5 ** 2)
        state = inflate_obstacles(live, grid.resolution, costmap.config, costmap.unknown)
        new_person += _time(lambda: planner.plan(start, goal, state), args.repeats, cpu["new"])
        expanded.append(planner.plan(start, goal, state).expanded)
        old_person += _time(lambda: previous_replan(grid, costmap.config, live, start, goal, planner), args.repeats,
                            cpu["old"])
        s, g = planner.cell_of(start, "s"), planner.cell_of(goal, "g")
        heap_person += _time(lambda: astar_reference(blocked_border(state.cell_cost), grid.resolution,
                                                     s[0] * cols + s[1], g[0] * cols + g[1]), 1, cpu["heap"])
    print(f"part 1 — cores on the office map ({cols}x{rows} cells at {grid.resolution} m), goal {goal.tolist()}")
    print(f"  first plan (static heuristic for the goal, once)   [ms] {first:7.2f}")
    print(f"  A* replan, nobody about                            [ms] {_stats(new_free)}")
    print(f"  A* replan, a person 2 m ahead                      [ms] {_stats(new_person)}"
          f"   ({int(statistics.median(expanded))} cells settled, median)")
    print(f"  previous: graph rebuild + full Dijkstra, person    [ms] {_stats(old_person)}")
    print(f"  textbook heapq A* (octile heuristic), person       [ms] {_stats(heap_person)}")
    ratio = statistics.median(old_person) / statistics.median(new_person)
    cpu_ms = {k: statistics.median(v) for k, v in cpu.items()}
    print(f"  → A* replans {ratio:.1f}× faster than the previous Dijkstra with a person ahead, "
          f"{statistics.median(old_person) / statistics.median(new_free):.0f}× with nobody about; "
          f"target ≤ 10 ms: {'OK' if statistics.median(new_person) <= 10 else 'ABOVE'}")

    layer = costmap.obstacle_layer
    cam, pose, depth = frame.intrinsics, frame.world_from_camera, frame.depth
    stamp = [0.0]

    def update():
        stamp[0] += 0.05
        assistant.add_depth(depth, cam, pose, stamp[0])
        return costmap.update()
    observe = _time(lambda: layer.add_depth(depth, cam, pose, stamp[0]), 20)
    full = _time(update, 20)
    assistant.set_subject(stamp[0], *planar_pose(pose, axis=2))
    assistant.replan()
    dwa = _time(lambda: assistant.velocity_hint((0.5, 0.0)), 50)
    print(f"  costmap from a {cam.width}x{cam.height} depth frame: marking + clearing [ms] {_stats(observe)}")
    print(f"  … + inflating static and live layers                [ms] {_stats(full)}")
    print(f"  DWA step (189 commands × 20 roll-out points)         [ms] {_stats(dwa)}")
    print(f"  on this thread's CPU time, a person ahead: A* {cpu_ms['new']:.2f} ms, previous {cpu_ms['old']:.2f} ms "
          f"({cpu_ms['old'] / cpu_ms['new']:.1f}×), textbook {cpu_ms['heap']:.2f} ms ({cpu_ms['heap'] / cpu_ms['new']:.1f}×)")
    return {"previous_dijkstra": cpu_ms["old"] / cpu_ms["new"], "textbook_astar": cpu_ms["heap"] / cpu_ms["new"]}


def graph_bench(args) -> int:
    from geometry_msgs.msg import Twist
    from sensor_msgs.msg import Image

    from raspv_bringup.testing import Probe, RunningGraph, claim_private_domain
    from raspv_common import topics
    from raspv_common.qos import COMMAND_QOS

    domain = claim_private_domain()
    workdir = Path(tempfile.mkdtemp(prefix="raspv-bench-nav-"))
    g = RunningGraph(REPO / "config" / "navigation.yaml", workdir,
                     ["bridge.port:=0", "bridge.tcp_port:=-1", f"sim.log_dir:={workdir}"])
    probe = Probe("bench_nav")
    try:
        g.wait_for_output(r"building map from", timeout=120)
        images = probe.subscribe(topics.SPV_IMAGE, Image)
        images.wait(5, timeout=120)
        cmd = probe.publisher(topics.CMD_VEL, Twist, COMMAND_QOS, wait_for_subscribers=1)
        relay = probe.node.create_subscription(Twist, topics.NAV_CMD_VEL_HINT, cmd.publish, COMMAND_QOS)
        images.messages.clear()
        images.stamps.clear()
        start = time.monotonic()
        while time.monotonic() - start < args.seconds and "reached at" not in g.output:
            time.sleep(0.2)
        elapsed = time.monotonic() - start
        received = len(images.messages)
        probe.node.destroy_subscription(relay)
        cmd.publish(Twist())
    finally:
        probe.close()
        g.stop()
    out = g.output
    spv = re.search(r"spv: (\d+) display frames, (\d+) dropped, tick median ([\d.]+) ms", out)
    plan = re.search(r"planner: (.+)", out)
    print(f"part 2 — config/navigation.yaml (ROS domain {domain}), a scripted subject following the hint, "
          f"{elapsed:.0f} s")
    print(f"  /spv/image received: {received / elapsed:.1f} Hz")
    if spv:
        shown, dropped = int(spv.group(1)), int(spv.group(2))
        print(f"  spv display: {shown} frames shown, {dropped} dropped ({100 * dropped / max(1, shown + dropped):.1f} %), "
              f"tick median {spv.group(3)} ms")
    if plan:
        print(f"  planner node: {plan.group(1)}")
    goal = re.search(r"goal 'bin' reached at t = ([\d.]+) s", out)
    collisions = len(re.findall(r"collision #", out))
    print(f"  run: {'goal reached at t = ' + goal.group(1) + ' s' if goal else 'goal not reached in time'}, "
          f"{collisions} collisions")
    return 0


def measure(args: argparse.Namespace) -> dict[str, float]:
    """Part 1 (and part 2 unless ``--core-only``), printed; part 1's ratios."""
    ratios = core_bench(args)
    if not args.core_only:
        graph_bench(args)
    return ratios


def run(args: argparse.Namespace) -> int:
    from raspv_bench.ratios import report

    report(args, measure(args))
    return 0
