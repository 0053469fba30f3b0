"""`raspv bench spv-kills`: `kill -9` the spv node again and again while a headset watches, and
time the bridge's no-data ring (issue 36).

A graph (synthetic RGB-D source → spv at 50 Hz with ``restart: true`` and its warm spare →
bridge) runs on a private ROS domain; a watching client (the reference client, raw images over
the WebSocket) counts every frame it receives. Each kill waits until the warm spare is ready
(so the replacement registers under the same name within a few hundred ms, the case that showed
a 1.04 s freeze), kills the spv process, and measures from the kill

- ``ring``: the first frame made after the kill (the bridge's ring, unless the new spv process
  is faster), by its stamp (when it was made: a client that lags on a loaded machine receives
  it later, by ``lag``, the client's delay behind the frames' stamps before the kill),
- ``gap``: the longest time the client went without any frame, from 0.5 s before the kill to
  0.5 s after the new process's first frame with camera content (shifted by ``lag``; until then
  the new process may stall computing its first depth frame),
- ``back``: the new process's first frame (at the probe),
- ``made gap``: the longest time between the stamps of the frames the client got in that window
  (when they were made; a gap only in ``gap`` is the client's own lateness on a loaded machine),
- ``spv gap``: the longest time between the new spv process's own frames (their stamps, at the
  probe) in that window: a stall while it starts, which the bridge's ring must fill,

and what the bridge said: its "no frames from the spv node (… its node gone)" line, the verdict
the ring followed. Figures under load are noisy; the load average is printed with them.
"""
from __future__ import annotations

import argparse
import asyncio
import os
import re
import signal
import statistics
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

QUICK = {"kills": 1}
SPV_RATE_HZ = 50.0
SETTLE_S = 0.5           # frames before the kill and after the new process's first one, in the gap window


@dataclass
class KillFigures:
    ring_s: float           # kill → first frame made after it (its stamp)
    lag_s: float            # the client's receipt behind the frames' stamps just before the kill
    gap_s: float            # the client's longest time without a frame around the kill
    back_s: float           # kill → the new spv process's first frame (at the probe)
    gap_at_s: float = 0.0   # kill → the start of that longest gap (the client's receipt, less its lag)
    spv_gap_s: float = 0.0  # the longest time between the new spv process's frames in the gap's window
    made_gap_s: float = 0.0  # the longest time between the stamps of the frames the client got (made, not received)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--kills", type=int, default=20, help="SIGKILLs of the spv node (default 20)")
    parser.add_argument("--timeout", type=float, default=90.0, help="give up on a restart after this [s]")


def graph_spec() -> dict:
    return {"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "spv", "restart": True},
                                 {"kind": "bridge"}],
                       "env": {"RASPV_STARTUP_REPORT": "1"}},
            "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120}},
            "spv": {"ros__parameters": {"mode": "depth", "width": 160, "rate": SPV_RATE_HZ}},
            "bridge": {"ros__parameters": {"port": 0, "tcp_port": -1}}}


class Watcher:
    """A watching headset client in a thread of its own: the receipt time (wall clock) and image
    stamp of every frame."""

    def __init__(self, url: str) -> None:
        from raspv_hmd.reference_client import ClientOptions, parse_endpoint, run_client

        self.frames: list[tuple[float, float]] = []        # (received, image stamp)
        self.error: BaseException | None = None
        self._loop = asyncio.new_event_loop()
        options = ClientOptions(role="watch", format="raw", duration_s=24 * 3600.0, head=None,
                                on_frame=lambda now, header, _image: self.frames.append((now, header.stamp)))
        self._main = run_client(parse_endpoint(url), options, connect_timeout=30.0)
        self._task: asyncio.Task | None = None
        self._thread = threading.Thread(target=self._run, daemon=True, name="watcher")
        self._thread.start()

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        self._task = self._loop.create_task(self._main)
        try:
            self._loop.run_until_complete(self._task)
        except asyncio.CancelledError:
            pass
        except Exception as exc:  # noqa: BLE001 - reported by the caller, with the graph's output
            self.error = exc

    def wait_frames(self, count: int, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while len(self.frames) < count:
            if self.error is not None or time.monotonic() > deadline:
                raise TimeoutError(f"the watcher got {len(self.frames)} frames ({self.error!r})")
            time.sleep(0.05)

    def close(self) -> None:
        if self._task is not None:
            self._loop.call_soon_threadsafe(self._task.cancel)
        self._thread.join(timeout=10)


def kill_spv(kills: int, timeout: float = 90.0, report=print) -> tuple[list[KillFigures], str]:
    """Run the graph, kill its spv node ``kills`` times; (figures per kill, the graph's output
    until the last kill was measured, and a ``topic seen:`` line per topic with an unknown node
    name in it)."""
    from raspv_msgs.msg import PhospheneFrame

    from raspv_bringup.supervisor import MAX_RESTARTS, RESTART_WINDOW_S
    from raspv_bringup.testing import Probe, RunningGraph
    from raspv_common import topics
    from raspv_spv import staleness

    probe = Probe("bench_spv_kills")
    g = RunningGraph(graph_spec(), Path(tempfile.mkdtemp(prefix="raspv-bench-spv-kills-")))
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    watcher = None
    out: list[KillFigures] = []
    during = ""
    try:
        url = g.wait_for_output(r"open (http://127\.0\.0\.1:\d+/) in a browser", timeout=timeout).group(1)
        watcher = Watcher(url)
        watcher.wait_frames(2 * int(SPV_RATE_HZ), timeout)          # 2 s of frames: the periods are learnt
        killed_at: list[float] = []
        for k in range(kills):
            g.wait_for_lines(r"^\[spv\] startup: imports done", 2 + k, timeout)   # its warm spare is ready
            time.sleep(1.0 + SETTLE_S)        # (the spare's imports compete for the CPU; frames flow again)
            if len(killed_at) >= MAX_RESTARTS:  # the launcher gives up after more restarts than that in its window
                time.sleep(max(0.0, killed_at[-MAX_RESTARTS] + RESTART_WINDOW_S + 1.0 - time.monotonic()))
            killed_at.append(time.monotonic())
            pid = g.pid_of("spv")
            t_kill = time.time()
            os.kill(pid, signal.SIGKILL)
            back = frames.wait(1, timeout=timeout, predicate=lambda m: _stamp(m.header.stamp) > t_kill)[0]
            t_back = _stamp(back.header.stamp)
            # its first frame with camera content: until then it may still stall (its first depth frame)
            content = frames.wait(1, timeout=timeout, predicate=lambda m: _stamp(m.header.stamp) > t_kill
                                  and m.mode != staleness.NO_DATA)[0]
            t_end = _stamp(content.header.stamp) + SETTLE_S
            deadline = time.monotonic() + timeout
            while not any(stamp > t_end for _, stamp in list(watcher.frames)):
                if time.monotonic() > deadline:
                    raise TimeoutError(f"the watcher got no frame after the restart ({watcher.error!r})")
                time.sleep(0.05)
            got = sorted(list(watcher.frames))
            ring = min(stamp for _, stamp in got if stamp > t_kill) - t_kill
            before = [r - stamp for r, stamp in got if t_kill - 1.0 <= stamp < t_kill]
            lag = statistics.median(before) if before else 0.0
            window = [r for r, _ in got if t_kill + lag - SETTLE_S <= r <= t_end + lag]
            gap, gap_from = max((b - a, a) for a, b in zip(window, window[1:]))
            own = sorted(s for m in list(frames.messages) if t_back <= (s := _stamp(m.header.stamp)) <= t_end)
            spv_gap = max((b - a for a, b in zip(own, own[1:])), default=0.0)
            made = sorted(stamp for _, stamp in got if t_kill - SETTLE_S <= stamp <= t_end)
            made_gap = max(b - a for a, b in zip(made, made[1:]))
            out.append(KillFigures(ring, lag, gap, t_back - t_kill, gap_from - lag - t_kill, spv_gap, made_gap))
            report(f"  kill {k + 1:>2}: ring after {ring * 1e3:4.0f} ms (client lag {lag * 1e3:3.0f} ms), longest gap "
                   f"{gap * 1e3:4.0f} ms from {(gap_from - lag - t_kill) * 1e3:+5.0f} ms (by the stamps "
                   f"{made_gap * 1e3:4.0f} ms; the new spv's own {spv_gap * 1e3:4.0f} ms), "
                   f"new spv's first frame after {t_back - t_kill:.2f} s (load {os.getloadavg()[0]:.1f})")
            with frames._cond:
                frames.messages.clear()
                frames.stamps.clear()
        during = g.output                    # (stopping the graph ends spv before the bridge: one more ring line)
    except TimeoutError as exc:
        raise TimeoutError(f"{exc}; threads (name:state:wait) of the bridge: {_threads(g.pid_of('bridge'))}; of spv: "
                           f"{_threads(g.pid_of('spv'))}; the graph's output:\n{g.output[-4000:]}") from None
    finally:
        if watcher is not None:
            watcher.close()
        probe.unsubscribe(frames)
        topics_seen = [name for name, _ in probe.node.get_topic_names_and_types()]
        probe.close()
        g.stop()
    unknown = [t for t in topics_seen if "UNKNOWN" in t]
    return out, during + "".join(f"\ntopic seen: {t}" for t in unknown)


def _threads(pid: int) -> str:
    """name:state:wait channel of each thread of ``pid`` (what a stuck process waits on)."""
    out = []
    for task in sorted(Path(f"/proc/{pid}/task").glob("*")):
        try:
            comm = (task / "comm").read_text().strip()
            state = (task / "stat").read_text().rsplit(")", 1)[1].split()[0]
            out.append(f"{comm}:{state}:{(task / 'wchan').read_text().strip()}")
        except OSError:
            continue
    return ", ".join(out)


def _stamp(t) -> float:
    return t.sec + 1e-9 * t.nanosec


def run(args: argparse.Namespace) -> int:
    from raspv_bringup.testing import claim_private_domain

    domain = claim_private_domain()
    print(f"raspv bench spv-kills (domain {domain}): synthetic 160x120 10 Hz → spv (depth, {SPV_RATE_HZ:.0f} Hz, "
          f"restart: true, warm spare) → bridge, one watching client; SIGKILL of spv {args.kills} times")
    figures, output = kill_spv(args.kills, args.timeout)
    rings = [f.ring_s * 1e3 for f in figures]
    gaps = [f.gap_s * 1e3 for f in figures]
    own = [f.spv_gap_s * 1e3 for f in figures]
    made = [f.made_gap_s * 1e3 for f in figures]
    gone = len(re.findall(r"no frames from the spv node \(.*its node gone\)", output))
    print(f"  ring after the kill: median {statistics.median(rings):.0f} ms, max {max(rings):.0f} ms; longest gap "
          f"without frames: median {statistics.median(gaps):.0f} ms, max {max(gaps):.0f} ms (target 300 ms); "
          f"{gone} of {len(figures)} rings judged 'its node gone'; longest gap by the stamps of the frames the "
          f"client got: median {statistics.median(made):.0f} ms, max {max(made):.0f} ms; the new spv's own longest gap: median {statistics.median(own):.0f} ms, max {max(own):.0f} ms; load average {os.getloadavg()[0]:.1f}")
    return 0
