"""Chaos: nodes with `restart: true` killed with SIGKILL come back — from a warm spare or started
cold — and the exit table reports the restarts; a launch whose node fails at start stops the
others without any traceback reaching the user. (The bound on the frozen image while a node is
down is part B of issue 16.)"""
from __future__ import annotations

import os
import re
import signal
import time

import pytest
from raspv_msgs.msg import PhospheneFrame

from raspv_common import topics

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def _stamp(t) -> float:
    return t.sec + 1e-9 * t.nanosec


def _pid(g, name: str) -> int:
    """The newest pid of node ``name`` in the launcher's own lines."""
    found = re.findall(rf"{name} \(\w+, pid (\d+)\)|node '{name}' ended .*?pid (\d+)\)", g.output)
    return int([a or b for a, b in found][-1])


def _wait_lines(g, pattern: str, count: int, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while len(re.findall(pattern, g.output, re.M)) < count:
        assert g.running(), g.output[-3000:]
        assert time.monotonic() < deadline, f"{count} x {pattern!r} not seen:\n{g.output[-3000:]}"
        time.sleep(0.1)


def test_killed_nodes_with_restart_come_back_and_the_exit_table_says_so(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"},
                                    {"kind": "scene", "restart": True, "spare": False},
                                    {"kind": "spv", "restart": True}],
                          "env": {"RASPV_STARTUP_REPORT": "1"}},
               "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120}},
               "spv": {"ros__parameters": {"mode": "wall_obstacles", "width": 200, "rate": 20.0, "temporal": False}}})
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    frames.wait(1, timeout=120, predicate=lambda m: _stamp(m.source_stamp) > 0)

    # spv: its warm spare (imports done, started a few seconds after it) takes over
    _wait_lines(g, r"^\[spv\] startup: imports done", 2)
    t_kill = time.time()
    os.kill(_pid(g, "spv"), signal.SIGKILL)
    g.wait_for_output(r"node 'spv' ended \(killed by signal 9\); restarting it \(warm spare, pid \d+\)", timeout=30)
    frames.wait(1, timeout=60, predicate=lambda m: _stamp(m.header.stamp) > t_kill and _stamp(m.source_stamp) > t_kill)

    # scene (no spare): started again from scratch; the phosphenes follow new scene frames again
    t_kill = time.time()
    os.kill(_pid(g, "scene"), signal.SIGKILL)
    g.wait_for_output(r"node 'scene' ended \(killed by signal 9\); restarting it \(pid \d+\)", timeout=30)
    frames.wait(1, timeout=120, predicate=lambda m: _stamp(m.source_stamp) > t_kill)
    probe.unsubscribe(frames)

    assert g.running()
    assert g.stop() == 0
    table = g.output[g.output.index("resources per node"):]
    rows = {m.group(1): (int(m.group(2)), m.group(3).strip())
            for m in re.finditer(r"^(\w+)\s+\w+\s+\S+\s+\d+\s+[\d.]+\s+(\d+)\s+(.*)$", table, re.M)}
    assert rows["scene"] == (1, "killed by signal 9") and rows["spv"] == (1, "killed by signal 9"), table
    assert rows["cam"] == (0, "-"), table
    assert "Traceback" not in g.output


def test_a_launch_that_fails_stops_its_nodes_without_tracebacks(graph):
    """spv refuses its parameters at start while the others are still importing: the graph stops,
    the one-line reason is shown, the interrupted nodes stay quiet, and the log folder is named."""
    g = graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "scene"}, {"kind": "sim"},
                                    {"kind": "spv"}]},
               "spv": {"ros__parameters": {"edge_low": 500.0, "edge_high": 100.0}}})
    g.proc.wait(timeout=120)
    out = g.output
    assert g.stop() == 1
    assert "edge_low (500.0) must not exceed edge_high (100.0)" in out
    assert "Traceback" not in out and "KeyboardInterrupt" not in out and "Fatal Python error" not in out, out
    m = re.search(r"the full output of every node is in (\S+)/", out)
    assert m and os.path.isfile(os.path.join(m.group(1), "spv.log")), out
