"""Chaos: nodes with `restart: true` killed with SIGKILL come back — from a warm spare or started
cold — and the exit table reports the restarts; a launch whose node fails at start stops the
others without any traceback reaching the user. While they are down the headset image
must never freeze (issue 16 part B): the spv node's stale-input fallback, measured on a turning
head."""
from __future__ import annotations

import math
import os
import re
import signal
import threading
import time

import pytest
from geometry_msgs.msg import QuaternionStamped
from raspv_msgs.msg import PhospheneFrame
from sensor_msgs.msg import Image

from raspv_common import topics
from raspv_common.qos import COMMAND_QOS

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def _stamp(t) -> float:
    return t.sec + 1e-9 * t.nanosec


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
    g.wait_for_lines(r"^\[spv\] startup: imports done", 2)
    t_kill = time.time()
    os.kill(g.pid_of("spv"), signal.SIGKILL)
    g.wait_for_output(r"node 'spv' ended \(killed by signal 9\); restarting it \(warm spare, pid \d+\)", timeout=30)
    frames.wait(1, timeout=60, predicate=lambda m: _stamp(m.header.stamp) > t_kill and _stamp(m.source_stamp) > t_kill)

    # scene (no spare): started again from scratch; the phosphenes follow new scene frames again
    t_kill = time.time()
    os.kill(g.pid_of("scene"), signal.SIGKILL)
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


# -- the headset image while nodes die (issue 16 part B) ------------------------------------------

# The README's figures, asserted with the margin a loaded 2-core machine needs (sim, scene, spv,
# bridge and this probe share the two cores with other test sessions):
STALE_TARGET_S = 0.3       # stale inputs detected and shown within this (raspv_spv.staleness)
STALE_MARGIN_S = 0.2       # scheduling under load: 235–282 ms measured in 6 runs under load (README)
RESTART_TARGET_S = 1.5     # kill -9 of spv → the warm spare's first frame
RESTART_MARGIN_S = 1.0     # DDS discovery of the promoted spare under load: 0.2–1.8 s measured (README)
HEAD_HZ, HEAD_YAW_DEG, HEAD_PITCH_DEG, HEAD_SWEEP_HZ = 30.0, 25.0, 20.0, 0.4


class HeadTurner(threading.Thread):
    """Turns the avatar's head (/head/orientation): yaw sweeping ±25° at 0.4 Hz, looking 20° down."""

    def __init__(self, probe) -> None:
        super().__init__(daemon=True)
        self.probe, self.stop = probe, threading.Event()
        self.pub = probe.publisher(topics.HEAD_ORIENTATION, QuaternionStamped, qos=COMMAND_QOS,
                                   wait_for_subscribers=1, timeout=120)

    def run(self) -> None:
        t0 = time.monotonic()
        while not self.stop.wait(1.0 / HEAD_HZ):
            yaw = math.radians(HEAD_YAW_DEG) * math.sin(2 * math.pi * HEAD_SWEEP_HZ * (time.monotonic() - t0))
            pitch = math.radians(HEAD_PITCH_DEG)
            m = QuaternionStamped()
            m.header.stamp, m.header.frame_id = self.probe.node.get_clock().now().to_msg(), "base_link"
            cy, sy, cp, sp = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(pitch / 2), math.sin(pitch / 2)
            m.quaternion.x, m.quaternion.y, m.quaternion.z, m.quaternion.w = -sy * sp, cy * sp, sy * cp, cy * cp
            self.pub.publish(m)


def longest_unchanged_s(images, start: float, end: float) -> float:
    """Longest time an image stayed the same (from its first appearance to the first different
    one) among the /spv/image messages stamped in [start, end]."""
    seq = sorted((_stamp(m.header.stamp), hash(bytes(m.data))) for m in images)
    seq = [s for s in seq if start <= s[0] <= end]
    if not seq:
        return 0.0
    longest, run_start = 0.0, seq[0][0]
    for (t, h), (_, h_prev) in zip(seq[1:], seq):
        if h != h_prev:
            longest, run_start = max(longest, t - run_start), t
    return max(longest, seq[-1][0] - run_start)


def test_the_headset_image_never_freezes_while_scene_and_spv_are_killed(graph, probe):
    """sim + scene + spv + bridge with `restart: true`: scene killed → the depth fallback on live
    camera frames within the stale bound, the scene mode back after its restart; spv killed → its
    warm spare's frames. Figures printed (run with -s); the README's bounds asserted, each with the
    margin a loaded 2-core machine needs (stated above)."""
    mode = "chess_wall_obstacles"
    g = graph({"launch": {"nodes": [{"kind": "sim"}, {"kind": "scene", "restart": True, "spare": False},
                                    {"kind": "spv", "restart": True}, {"kind": "bridge"}],
                          "env": {"RASPV_STARTUP_REPORT": "1"}},
               "sim": {"ros__parameters": {"world": "office", "rate": 10.0, "width": 160, "height": 120}},
               "spv": {"ros__parameters": {"mode": mode, "width": 160, "rate": 25.0, "temporal": False}},
               "bridge": {"ros__parameters": {"port": 0, "tcp_port": -1}}})
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    images = probe.subscribe(topics.SPV_IMAGE, Image)
    head = HeadTurner(probe)
    head.start()
    try:
        first = frames.wait(1, timeout=120, predicate=lambda m: m.mode == mode and _stamp(m.source_stamp) > 0)[0]
        # a steady graph: the spv node has learnt its inputs' periods
        frames.wait(1, timeout=60, predicate=lambda m: m.mode == mode
                    and _stamp(m.source_stamp) > _stamp(first.source_stamp) + 1.5)

        # scene killed (restarted cold): the fallback on new camera frames, then the scene mode again
        t_kill = time.time()
        os.kill(g.pid_of("scene"), signal.SIGKILL)
        fallback = frames.wait(1, timeout=30, predicate=lambda m: _stamp(m.header.stamp) > t_kill and m.mode == "depth")[0]
        g.wait_for_output(r"node 'scene' ended \(killed by signal 9\); restarting it \(pid \d+\)", timeout=30)
        # (its own result again: until the scene goes stale, new frames carry its last result)
        back = frames.wait(1, timeout=120, predicate=lambda m: m.mode == mode and _stamp(m.scene_stamp) > t_kill)[0]
        t_back = _stamp(back.header.stamp)
        shown_after = _stamp(fallback.header.stamp) - t_kill
        frozen = longest_unchanged_s(images.messages, t_kill - 1.0, t_back + 1.0)
        depth_sources = {_stamp(m.source_stamp) for m in frames.messages if m.mode == "depth"}
        print(f"\nscene killed: fallback shown after {shown_after * 1e3:.0f} ms, scene mode back after "
              f"{t_back - t_kill:.2f} s, longest unchanged image {frozen * 1e3:.0f} ms")
        print("\n".join(re.findall(r"^\[spv\].*stale input.*$", g.output, re.M)))
        assert len(depth_sources) > 1                         # live camera frames, not the last scene frame
        assert shown_after < STALE_TARGET_S + STALE_MARGIN_S
        assert frozen < STALE_TARGET_S + STALE_MARGIN_S

        # spv killed: its warm spare publishes frames, in the scene mode
        g.wait_for_lines(r"^\[spv\] startup: imports done", 2)
        t_kill = time.time()
        os.kill(g.pid_of("spv"), signal.SIGKILL)
        g.wait_for_output(r"node 'spv' ended \(killed by signal 9\); restarting it \(warm spare, pid \d+\)", timeout=30)
        first = images.wait(1, timeout=60, predicate=lambda m: _stamp(m.header.stamp) > t_kill)[0]
        again = frames.wait(1, timeout=120, predicate=lambda m: m.mode == mode and _stamp(m.header.stamp) > t_kill
                            and _stamp(m.source_stamp) > t_kill)[0]
        gap = _stamp(first.header.stamp) - t_kill
        content = min(_stamp(m.header.stamp) for m in frames.messages
                      if _stamp(m.header.stamp) > t_kill and _stamp(m.source_stamp) > 0) - t_kill
        # until the restarted process's subscriptions are matched (DDS discovery) it shows a dark image
        print(f"spv killed: first frame of the restarted spv after {gap:.2f} s (target 1.5 s), first camera "
              f"content after {content:.2f} s, scene mode after {_stamp(again.header.stamp) - t_kill:.2f} s")
        assert gap < RESTART_TARGET_S + RESTART_MARGIN_S
    finally:
        head.stop.set()
        head.join(timeout=5)
        probe.unsubscribe(frames)
        probe.unsubscribe(images)
    assert g.stop() == 0 and "Traceback" not in g.output
    # the DDS segments the killed processes left in /dev/shm are gone (raspv_bringup/shm_cleanup.py)
    assert re.search(r"removed [1-9]\d* shared-memory segment", g.output), g.output[-2000:]
    print(re.findall(r"removed \d+ shared-memory segment.*", g.output))
