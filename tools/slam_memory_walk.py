"""SLAM's memory over a long recording, as ``raspv slam build`` uses the core (issue 32: "memory
≤ 1 GB after a 10-min walk").

Feeds every frame of a recording to :class:`raspv_slam.slam_system.SlamSystem` (background loop
closer, floor anchoring by the scene perception, as ``raspv slam build``), while a thread reads
the resident set of this process and of its children (the pose-graph process) every 0.5 s.
Every ``--every`` frames it prints the frame, its stamp, the keyframes, the loop closer's backlog
(keyframes waiting), the resident sets and their peaks so far; at the end it waits for the loop
closer, saves the map (the node does so every ``autosave_period``) and prints the peaks of each
phase. ``--trajectory`` writes the final trajectory (TUM format) for ``tools/slam_walk_report.py``,
``--online`` the poses as tracking gave them frame by frame (what the node publishes);
``--realtime`` feeds the frames at the pace of their stamps, as a camera would (the loop closer
gets the CPU tracking leaves, as in the node), instead of as fast as they are tracked.

At the last frame it also prints how many keyframes the loop closer has processed and their
latency (made to processed, waiting included) and time spent, p50 / p95. ``--drain-limit S``:
wait at most S seconds for the loop closer after the last frame; then the map is saved as it is (the keyframes are all there; edges and corrections
still waiting are not), the final trajectory is not written and the waiting keyframes are
dropped (nothing else in the core stops a backlog).

    python tools/slam_memory_walk.py walks/long_walk --map long_walk --trajectory walks/long_walk/slam.txt
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import psutil

MB = 2**20


class MemorySampler:
    """Resident set [MB] of this process (``own``) and of it with its children (``total``): now and
    the peaks since the last :meth:`phase`."""

    def __init__(self, period: float = 0.5) -> None:
        self._me = psutil.Process()
        self.period = period
        self.peak_own = self.peak_total = 0.0
        self.own = self.total = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="memory-sampler", daemon=True)
        self._thread.start()

    def read(self) -> tuple[float, float]:
        own = self._me.memory_info().rss
        total = own
        for child in self._me.children(recursive=True):
            try:
                total += child.memory_info().rss
            except psutil.Error:
                pass
        self.own, self.total = own / MB, total / MB
        self.peak_own, self.peak_total = max(self.peak_own, self.own), max(self.peak_total, self.total)
        return self.own, self.total

    def _run(self) -> None:
        while not self._stop.wait(self.period):
            self.read()

    def phase(self) -> tuple[float, float]:
        """(peak own, peak total) since the last call; starts a new phase."""
        self.read()
        out = (self.peak_own, self.peak_total)
        self.peak_own, self.peak_total = self.own, self.total
        return out

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording", help="a TUM-layout folder (raspv sim walk) or a bag")
    parser.add_argument("--map", help="save the map here at the end (a name or a folder)")
    parser.add_argument("--trajectory", help="write the final trajectory here (TUM format)")
    parser.add_argument("--every", type=int, default=250, help="print a line every N frames (default 250)")
    parser.add_argument("--online", help="write the poses as tracking gave them here (TUM format)")
    parser.add_argument("--drain-limit", type=float, help="wait at most this long [s] for the loop closer at the end")
    parser.add_argument("--frames", type=int, help="only the first N frames")
    parser.add_argument("--realtime", action="store_true",
                        help="feed the frames at their stamps' pace (as a camera would; default: as fast as tracked)")
    parser.add_argument("--max-seconds", type=float,
                        help="stop feeding frames after this long [s] (as Ctrl-C does), then drain, save and report")
    return parser


def main(argv: list[str] | None = None) -> int:
    from raspv_slam.recordings import RecordingError, open_recording

    args = parser().parse_args(argv)
    try:
        rec = open_recording(args.recording)
    except RecordingError as exc:
        print(f"slam_memory_walk: {exc}", file=sys.stderr)
        return 2
    from raspv_slam.config import SlamConfig

    return measure(rec.frames(), rec.intrinsics,
                   SlamConfig(distortion=rec.distortion, rolling_shutter_readout=rec.rolling_shutter), args)


def measure(frames, intrinsics, config, args) -> int:
    """Build a map of ``frames`` (RecordingFrame-like: stamp, rgb, depth) and print the memory."""
    from raspv_perception.scene_config import SceneConfig
    from raspv_perception.scene_perception import ScenePerception
    from raspv_slam.evaluation import write_trajectory
    from raspv_slam.map_store import save_map
    from raspv_slam.slam_system import SlamSystem

    sampler = MemorySampler()
    scene = ScenePerception(SceneConfig())
    start = time.monotonic()
    print(f"start: resident set {sampler.read()[0]:.0f} MB", flush=True)
    slam = SlamSystem(intrinsics, config)
    online_stamps, online_poses = [], []
    drained = True
    try:
        for i, f in enumerate(_until_stopped(frames, start, args.max_seconds)):
            if args.frames is not None and i >= args.frames:
                break
            first_stamp = f.stamp if i == 0 else first_stamp
            if args.realtime:
                time.sleep(max(0.0, (f.stamp - first_stamp) - (time.monotonic() - start)))
            r = slam.process(f.stamp, f.rgb, f.depth)
            if r.map_from_camera is not None and r.map_id == 0:
                online_stamps.append(f.stamp)
                online_poses.append(r.map_from_camera)
            if r.map_from_camera is not None and f.depth is not None and not slam.map.anchored:
                s = scene.process(f.depth, intrinsics).structure
                if s.floor_found:
                    slam.anchor_to_floor(s.floor_plane, f.stamp)
            if i % args.every == 0:
                own, total = sampler.read()
                lc = slam.loop_closer
                backlog = lc.backlog if lc is not None else 0
                print(f"frame {i} t {f.stamp - first_stamp:.1f} s: {len(slam.map)} keyframes, "
                      f"loop-closer backlog {backlog} ({len(lc.busy_ms) if lc is not None else 0} processed), resident {own:.0f} MB (+children {total:.0f} MB), "
                      f"peaks {sampler.peak_own:.0f} / {sampler.peak_total:.0f} MB, {slam.counts}, "
                      f"{time.monotonic() - start:.0f} s", flush=True)
        walk = sampler.phase()
        if slam.loop_closer is not None:
            print(f"loop closer at the last frame: {_loop_closer_line(slam.loop_closer)}", flush=True)
        if args.online:
            write_trajectory(args.online, np.array(online_stamps), np.array(online_poses).reshape(-1, 4, 4))
        t0 = time.monotonic()
        lc = slam.loop_closer
        backlog = lc.backlog if lc is not None else 0
        while lc is not None and lc.busy and (args.drain_limit is None or time.monotonic() - t0 < args.drain_limit):
            time.sleep(0.5)
        drained = lc is None or not lc.busy
        drain = sampler.phase()
        print(f"walk: peaks {walk[0]:.0f} / {walk[1]:.0f} MB (own / with the pose-graph process); loop-closer backlog "
              f"{backlog} keyframes at the last frame, {'drained' if drained else 'NOT drained, still ' + str(lc.backlog)}"
              f" after {time.monotonic() - t0:.0f} s, peaks {drain[0]:.0f} / {drain[1]:.0f} MB", flush=True)
        if args.map:
            t0 = time.monotonic()
            save_map(slam.map, args.map)          # SlamSystem.save would wait for the loop closer first
            save = sampler.phase()
            print(f"save: {time.monotonic() - t0:.1f} s, peaks {save[0]:.0f} / {save[1]:.0f} MB", flush=True)
        if args.trajectory and drained:
            write_trajectory(args.trajectory, *slam.trajectory())
        lc = slam.loop_closer
        print(f"done: {len(slam.map)} keyframes, {len(slam.map.edges)} edges "
              f"({sum(e.kind == 'loop' for e in slam.map.edges)} loop), map {slam.map.nbytes / MB:.0f} MB in keyframes "
              f"and place database; loop closer {_loop_closer_line(lc) if lc else 'none'}; {slam.counts}; "
              f"{time.monotonic() - start:.0f} s", flush=True)
    finally:
        if not drained:
            slam.loop_closer.error = RuntimeError("stopped")     # the thread skips the keyframes still waiting
        slam.close()
        sampler.stop()
    return 0


def _loop_closer_line(lc) -> str:
    """Keyframes processed, latency and time per keyframe (p50 / p95 [ms]), optimisations."""
    latency = np.array(lc.latency_ms) if lc.latency_ms else np.zeros(1)
    busy = np.array(lc.busy_ms) if lc.busy_ms else np.zeros(1)
    return (f"{len(lc.busy_ms)} keyframes processed, latency p50 {np.percentile(latency, 50):.0f} / p95 "
            f"{np.percentile(latency, 95):.0f} ms, time p50 {np.percentile(busy, 50):.0f} / p95 "
            f"{np.percentile(busy, 95):.0f} ms ({busy.sum() / 1e3:.0f} s busy), {lc.optimisations} optimisations "
            f"({lc.whole_graph_optimisations} of the whole graph, {lc.whole_graph_for_loops} for a loop or merge), {lc.loop_edges} loop edges, {len(lc.rejected)} rejected")


def _until_stopped(frames, start: float, max_seconds: float | None):
    """The frames until ``max_seconds`` have passed since ``start`` or SIGINT (Ctrl-C) came."""
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    for f in frames:
        if stop.is_set() or (max_seconds is not None and time.monotonic() - start > max_seconds):
            print(f"stopped feeding frames after {time.monotonic() - start:.0f} s", flush=True)
            return
        yield f


if __name__ == "__main__":
    sys.exit(main())
