"""Dead or slow on a loaded machine (issue 21): sim + scene + spv with two CPU hogs beside them on
the same cores. The nodes are slow but alive, so the wearer keeps the configured representation —
no fallback, no stale episode. Then the scene node is stopped with SIGSTOP (alive to the kernel,
dead to the graph): the depth fallback shows within the stale bound; SIGCONT brings the mode back."""
from __future__ import annotations

import json
import multiprocessing
import os
import signal
import threading
import time

import pytest
from std_msgs.msg import String

from raspv_common import topics
from raspv_common.qos import LATCHED_QOS
from raspv_msgs.msg import PhospheneFrame

pytestmark = [pytest.mark.integration, pytest.mark.slow]

MODE = "chess_wall_obstacles"
LOADED_S = 20.0            # seconds watched with the hogs running
STALE_TARGET_S = 0.3       # a dead producer shown within this (raspv_spv.staleness)
# On a 2-core machine with two hogs beside the graph (and whatever else CI runs) the probe itself
# and the DDS liveliness assertions are scheduled late: allow this on top, stated, not hidden.
LOAD_MARGIN_S = 0.5


def _hog(stop) -> None:
    while not stop.is_set():
        sum(i * i for i in range(10_000))


def _stamp(t) -> float:
    return t.sec + 1e-9 * t.nanosec


class ShownModes:
    """(receipt time, mode shown, configured) of every /spv/frame (thread-safe)."""

    def __init__(self, probe) -> None:
        self.lock = threading.Lock()
        self.frames: list[tuple[float, str, str]] = []
        self.status: list[dict] = []
        probe.node.create_subscription(PhospheneFrame, topics.SPV_FRAME, self._frame, 10)
        probe.node.create_subscription(String, topics.SPV_STATUS, lambda m: self.status.append(json.loads(m.data)),
                                       LATCHED_QOS)

    def _frame(self, m) -> None:
        with self.lock:
            self.frames.append((time.time(), m.mode, m.configured_mode))

    def since(self, t: float) -> list[tuple[float, str, str]]:
        with self.lock:
            return [f for f in self.frames if f[0] >= t]

    def wait(self, predicate, timeout: float) -> tuple[float, str, str]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                hit = next((f for f in self.frames if predicate(f)), None)
            if hit is not None:
                return hit
            time.sleep(0.01)
        raise AssertionError(f"no such frame within {timeout} s; last {self.frames[-3:]}")


def test_slow_nodes_keep_the_mode_and_a_stopped_one_is_shown(graph, probe):
    g = graph({"launch": {"nodes": [{"kind": "sim"}, {"kind": "scene"}, {"kind": "spv"}]},
               "sim": {"ros__parameters": {"world": "office", "width": 320, "height": 240}},
               "spv": {"ros__parameters": {"mode": MODE, "width": 320, "temporal": False}}})
    shown = ShownModes(probe)
    start = time.time()
    shown.wait(lambda f: f[1] == MODE, timeout=180)
    time.sleep(3.0)                                           # settled: periods learnt
    stop = multiprocessing.Event()
    hogs = [multiprocessing.Process(target=_hog, args=(stop,), daemon=True) for _ in range(os.cpu_count() or 2)]
    for h in hogs:
        h.start()
    try:
        episodes0 = shown.status[-1]["stale_episodes"]
        t0 = time.time()
        time.sleep(LOADED_S)
        loaded = shown.since(t0)
        other = [f for f in loaded if f[1] != f[2]]
        episodes = shown.status[-1]["stale_episodes"] - episodes0
        print(f"\nwith {len(hogs)} CPU hogs for {LOADED_S:.0f} s: {len(loaded)} frames, {len(other)} not in the "
              f"configured mode, {episodes} stale episodes; producers {shown.status[-1].get('producers')}")
        assert len(loaded) > 10 * LOADED_S                    # the display kept going
        assert not other and episodes == 0, (other[:5], shown.status[-1])

        # the scene node stopped: dead to the graph (its DDS lease lapses) — the fallback, promptly
        scene = g.pid_of("scene")
        t_stop = time.time()
        os.kill(scene, signal.SIGSTOP)
        try:
            fallback = shown.wait(lambda f: f[0] > t_stop and f[1] == "depth", timeout=10)
        finally:
            os.kill(scene, signal.SIGCONT)
        t_cont = time.time()
        back = shown.wait(lambda f: f[0] > t_cont and f[1] == MODE, timeout=60)
        after = fallback[0] - t_stop
        print(f"scene stopped: depth fallback shown {1e3 * after:.0f} ms later (target {1e3 * STALE_TARGET_S:.0f} ms "
              f"+ {1e3 * LOAD_MARGIN_S:.0f} ms for the load), the mode back {back[0] - t_cont:.2f} s after SIGCONT")
        assert after < STALE_TARGET_S + LOAD_MARGIN_S
    finally:
        stop.set()
        for h in hogs:
            h.join(timeout=5)
    assert "Traceback" not in g.output
    assert time.time() - start < 600
