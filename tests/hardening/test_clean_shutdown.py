"""Every shipped graph stops cleanly (issue 36, item 4): launched as shipped (smaller images and
rates, the bridge on free ports, logs and maps in the test's folder), up once the phosphene
frames carry camera content, then stopped with SIGINT (one graph with SIGTERM) — and neither
the terminal nor any node's log holds a FATAL line, a traceback or an RCLError (before: the
camera node's "[FATAL] camera thread failed: RCLError(... context is invalid)", the spv display
thread's RCLError traceback, the scene node raising at Ctrl-C in the replay graph). The graphs
run in one test, two at a time (two lanes, each on a ROS domain of its own with its own probe,
each lane's graphs one after another): 51 s one at a time in the suite of 7 December."""
from __future__ import annotations

import os
import re
import signal
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from raspv_msgs.msg import PhospheneFrame

from raspv_bags.from_frames import RgbdBagWriter
from raspv_bringup.testing import Probe
from raspv_common import topics
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.ros_domains import lock_free_domain

pytestmark = [pytest.mark.integration, pytest.mark.slow]

CONFIG = Path(__file__).resolve().parents[2] / "config"
NOISE = re.compile(r"FATAL|Traceback|RCLError")
LIGHT = ["spv.width:=160", "spv.rate:=25.0", "bridge.port:=0", "bridge.tcp_port:=-1"]
SIM = ["sim.width:=160", "sim.height:=120", "sim.rate:=10.0", "sim.log_dir:="]


def _frames(n: int):
    camera = CameraIntrinsics.from_hfov(160, 120, 60.0)
    for i in range(n):
        depth = np.full((120, 160), 1.5 + 0.01 * i, np.float32)
        depth[80:] = np.linspace(1.0, 3.0, 40, dtype=np.float32)[:, None]      # a floor-like ramp
        yield 1.7e9 + i / 15, np.full((120, 160, 3), 8 * i, np.uint8), depth, camera


def _sources(tmp_path: Path) -> dict[str, list[str]]:
    """The overrides of each shipped graph: sources that need a file get a small one."""
    from raspv_camera.sdk_recordings import SourceFrame, write_realsense_recording

    bag = tmp_path / "replay_bag"
    with RgbdBagWriter(bag, "mcap") as out:
        for stamp, color, depth, camera in _frames(30):
            out.add(stamp, color, depth, camera)
    recording = write_realsense_recording(
        tmp_path / "camera.db3", [SourceFrame(c, (d * 1000).astype(np.uint16), s - 1.7e9) for s, c, d, _ in _frames(30)],
        CameraIntrinsics.from_hfov(160, 120, 60.0), fps=15)
    return {path.stem: LIGHT + ({"camera": [f"camera.file:={recording}"],
                                 "replay": [f"replay.bag:={bag}"]}.get(path.stem, SIM))
            for path in sorted(CONFIG.glob("*.yaml"))}


def _noisy(text: str) -> list[str]:
    """The noisy lines of a log; a traceback with its frames and exception (a CI failure must say
    where it came from, not only that there was one)."""
    lines, out, i = text.splitlines(), [], 0
    while i < len(lines):
        if NOISE.search(lines[i]):
            j = i + 1
            if lines[i].startswith("Traceback"):
                while j < len(lines) and lines[j].startswith((" ", "\t")):
                    j += 1
                j = min(j + 1, len(lines))          # the exception line
            out.append("\n".join(lines[i:j]))
            i = j
        else:
            i += 1
    return out


def _stop_cleanly(i: int, name: str, overrides: list[str], graph, probe, tmp_path: Path,
                  env: dict[str, str]) -> list[str]:
    """Start shipped graph ``name``, wait for camera content in its phosphene frames, stop it
    (SIGTERM for graph 0, SIGINT for the others); the noisy lines of its terminal and node logs."""
    workdir = tmp_path / name
    workdir.mkdir()
    t0 = time.monotonic()
    g = graph(CONFIG / f"{name}.yaml", overrides, env={**env, "ROS_LOG_DIR": str(workdir / "ros_log"),
                                                      "RASPV_MAPS_DIR": str(workdir / "maps")})
    frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
    try:
        frames.wait(1, timeout=180, predicate=lambda m: m.source_stamp.sec > 0)
    except TimeoutError:
        raise AssertionError(f"{name}: no phosphene frame with camera content:\n{g.output[-3000:]}") from None
    finally:
        probe.unsubscribe(frames)
    up = time.monotonic() - t0
    code = g.stop(signal.SIGTERM if i == 0 else signal.SIGINT)
    logs = {"terminal": g.output}
    logs.update({str(p.relative_to(workdir)): p.read_text(errors="replace")
                 for p in (workdir / "ros_log").rglob("*.log")})
    lines = [f"{name} {where}: {line}" for where, text in logs.items() for line in _noisy(text)]
    print(f"{name}: up after {up:.1f} s, stopped {time.monotonic() - t0 - up:.1f} s later, exit {code}, "
          f"{len(lines)} noisy lines (load {os.getloadavg()[0]:.1f})")
    assert code == 0, f"{name}: exit {code}\n{g.output[-3000:]}"
    return lines


def test_every_shipped_graph_stops_without_fatal_traceback_or_rclerror(graph, probe, tmp_path):
    sources = _sources(tmp_path)
    assert len(sources) == 7, sorted(sources)
    jobs = list(enumerate(sources.items()))
    domain, domain_lock = lock_free_domain()                 # the second lane's domain
    second_probe = Probe("clean_shutdown_lane2", domain_id=domain)
    lanes = [(probe, {}, jobs[0::2]), (second_probe, {"ROS_DOMAIN_ID": str(domain)}, jobs[1::2])]

    def run_lane(lane_probe, env, lane_jobs) -> list[str]:
        return [line for i, (name, overrides) in lane_jobs
                for line in _stop_cleanly(i, name, overrides, graph, lane_probe, tmp_path, env)]

    try:
        with ThreadPoolExecutor(max_workers=len(lanes)) as pool:
            futures = [pool.submit(run_lane, *lane) for lane in lanes]
            noisy = [line for f in futures for line in f.result()]
    finally:
        second_probe.close()
        domain_lock.close()
    assert not noisy, "\n".join(noisy[:40])
