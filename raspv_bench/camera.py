"""Camera drivers: SDK frame → published messages, and camera frame → phosphene image.

Part 1 (on one core) times each driver playing its SDK's own recording of 640×480 frames — the
TUM desk frame drifting sideways, as ``bench bag`` — from the SDK handing the frame over,
through registration, to the three ROS messages the node publishes (colour, depth 32FC1,
camera info). RealSense: the depth is recorded as a depth camera with its own intrinsics
(wider, 77°) 25 mm beside the colour camera sees it, so ``rs.align`` does real work. DepthAI:
``RecordMessage`` files (aligned on the device when recorded live). OpenNI2: the library's dummy
device (320×240, the only size it makes). Peer: the same frames read back from a RASPV bag
(``BagReader`` + decode). Target: ≤ 5 ms per 640×480 frame including registration.

Part 2 runs ``config/camera.yaml`` (camera + scene + odometry + spv + bridge) with the camera
node replaying the RealSense recording in a loop, and measures from a subscriber, for every
camera frame, the time from its stamp to the first ``/spv/frame`` whose ``source_stamp`` is
that frame (the phosphene image built from it: its depth, with the newest scene result carried
into it by the spv node's ``carry_scene``, or its own), and to the first built from its own scene
result (``scene_stamp`` = ``source_stamp``). Target: p95 ≤ 40 ms. Peer: the same graph fed by
the ``replay`` node from the RASPV bag.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

TUM = Path(__file__).resolve().parent.parent / "tests" / "data" / "rgbd"
DRIVER_TARGET_MS = 5.0
E2E_TARGET_MS = 40.0
BASELINE_M = (0.025, 0.0, 0.0)


# --quick (raspv_bench.bench_cli): a smoke run in seconds, run by tests/bench
QUICK = {"frames": 30, "seconds": 3.0, "no_peer": True}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=int, default=150, help="frames in the recordings (default 150, 5 s at 30 Hz)")
    parser.add_argument("--fps", type=float, default=30.0, help="frame rate of the recordings (default 30)")
    parser.add_argument("--seconds", type=float, default=12.0, help="part 2 measuring time per graph [s] (default 12)")
    parser.add_argument("--no-graph", action="store_true", help="skip part 2")
    parser.add_argument("--no-peer", action="store_true", help="part 2: skip the replay-node peer")
    parser.add_argument("--keep", metavar="DIR", help="write the recordings here and keep them")
    parser.add_argument("--set", action="append", default=[], metavar="NODE.PARAM:=VALUE",
                        help="part 2: parameter override (repeatable), e.g. spv.temporal:=false")


def _stats(v: list[float]) -> str:
    if not v:
        return "n/a"
    a = np.asarray(v)
    return f"median {np.median(a):6.2f}  p95 {np.percentile(a, 95):6.2f}  max {a.max():6.2f}"


def tum_drift_frames(n: int, rate: float = 30.0):
    """(colour RGB, depth m, intrinsics, time s) of the TUM desk frame drifting ±20 px sideways."""
    import cv2

    from raspv_common.intrinsics import CameraIntrinsics
    from raspv_common.rgbd_files import read_color, read_depth_scaled

    color = read_color(TUM / "tum_color.png")
    depth = read_depth_scaled(TUM / "tum_depth.png", 1.0 / 5000.0)
    K = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
    for i in range(n):
        dx = 20.0 * np.sin(2 * np.pi * i / max(n, 1))
        M = np.float32([[1, 0, dx], [0, 1, 0]])
        c = cv2.warpAffine(color, M, (640, 480), flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
        d = cv2.warpAffine(depth, M, (640, 480), flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
        yield c, d, K, 100.0 + i / rate


def make_recordings(folder: Path, n: int, fps: float = 30.0) -> dict[str, Path]:
    """The RealSense (.db3), DepthAI (directory) and OpenNI2 (.oni) recordings and a RASPV bag."""
    from raspv_bags.from_frames import RgbdBagWriter
    from raspv_camera.rgbd_frame import CameraError
    from raspv_camera.sdk_recordings import (SourceFrame, depth_seen_from, write_depthai_recording,
                                             write_openni2_dummy_recording, write_realsense_recording)
    from raspv_common.intrinsics import CameraIntrinsics

    depth_cam = CameraIntrinsics(640, 480, 400.0, 400.0, 320.5, 238.5)
    frames = list(tum_drift_frames(n, fps))
    K = frames[0][2]
    rs_frames = (SourceFrame(c, np.nan_to_num(depth_seen_from(d, K, depth_cam, BASELINE_M) * 1000).astype(np.uint16), t)
                 for c, d, _, t in frames)
    out = {"realsense": write_realsense_recording(folder / "tum.db3", rs_frames, K, depth_cam, fps=int(round(fps)),
                                                  depth_to_color_m=BASELINE_M)}
    mm = (SourceFrame(c, np.nan_to_num(d * 1000).astype(np.uint16), t) for c, d, _, t in frames)
    for sdk, write in (("depthai", lambda: write_depthai_recording(folder / "tum_depthai", mm, K)),
                       ("openni2", lambda: write_openni2_dummy_recording(folder / "dummy.oni", 60)[0])):
        try:
            out[sdk] = write()
        except CameraError as exc:
            print(f"  no {sdk} recording: {exc}")
    with RgbdBagWriter(folder / "tum_bag") as bag:
        for c, d, KK, t in frames:
            bag.add(t, c, d, KK)
    out["bag"] = folder / "tum_bag"
    return out


def driver_costs(sdk: str, path: Path) -> tuple[list[float], list[float], str]:
    """Per frame: (the driver's own work on a frame the SDK handed over [ms] — pairing,
    registration, copies; not the wait for the SDK's file reader —, building the messages [ms])
    and the frame size."""
    from raspv_camera.camera_driver import CameraSettings
    from raspv_camera.camera_node import depth_for_encoding
    from raspv_camera.drivers import make_driver
    from raspv_camera.rgbd_frame import EndOfRecording
    from raspv_common.conversions import array_to_image, intrinsics_to_camera_info

    read, convert, size = [], [], ""
    with make_driver(sdk, CameraSettings(file=str(path))) as driver:
        while True:
            try:
                frame = driver.read(2.0)
            except EndOfRecording:
                break
            if frame is None:
                continue
            t1 = time.perf_counter()
            array_to_image(frame.color, "rgb8")
            array_to_image(depth_for_encoding(frame, "32FC1"), "32FC1")
            intrinsics_to_camera_info(frame.intrinsics, distortion=frame.distortion)
            t2 = time.perf_counter()
            read.append(driver.frame_ms)
            convert.append(1e3 * (t2 - t1))
            size = f"{frame.color.shape[1]}x{frame.color.shape[0]}"
    return read, convert, size


def bag_costs(path: Path) -> list[float]:
    from raspv_bags.reader import BagReader
    from raspv_common import topics
    from raspv_common.conversions import depth_from_image, rgb_from_image

    out = []
    with BagReader(path) as reader:
        it = reader.messages([topics.COLOR, topics.DEPTH, topics.CAMERA_INFO])
        t0 = time.perf_counter()
        for m in it:
            msg = reader.decode(m)
            if m.topic == topics.COLOR:
                rgb_from_image(msg)
            elif m.topic == topics.DEPTH:
                depth_from_image(msg)
            else:
                t1 = time.perf_counter()
                out.append(1e3 * (t1 - t0))
                t0 = t1
    return out


def part1(recordings: dict[str, Path]) -> dict:
    cpu = sorted(os.sched_getaffinity(0))[-1]
    os.sched_setaffinity(0, {cpu})
    print(f"part 1: driver cost per frame on one core (cpu {cpu}), SDK recordings of the drifting TUM frame")
    results = {}
    for sdk in ("realsense", "depthai", "openni2"):
        if sdk not in recordings:
            continue
        try:
            read, convert, size = driver_costs(sdk, recordings[sdk])
        except Exception as exc:
            print(f"  {sdk:9s} skipped: {exc}")
            continue
        total = [a + b for a, b in zip(read, convert)]
        results[sdk] = total
        what = {"realsense": "pair + align + copy", "depthai": "pair + copy", "openni2": "pair + copy"}[sdk]
        print(f"  {sdk:9s} {size:8s} {len(convert):4d} frames  {what}: {_stats(read)}")
        print(f"  {'':9s} {'':8s} {'':11s} messages: {_stats(convert)}   total {_stats(total)} ms")
    peer = bag_costs(recordings["bag"])
    print(f"  peer: RASPV bag read + decode, 640x480: {_stats(peer)} ms")
    if "realsense" in results and peer:
        m = float(np.median(results["realsense"]))
        print(f"  RealSense driver median {m:.2f} ms = {m / DRIVER_TARGET_MS:.2f}x the {DRIVER_TARGET_MS:g} ms target, "
              f"{m / float(np.median(peer)):.1f}x the bag peer")
    os.sched_setaffinity(0, set(range(os.cpu_count() or 1)))
    return results


class GraphFailed(RuntimeError):
    """The graph stopped, or showed no phosphene frame from a camera frame within 120 s (its output)."""


def _graph_latency(source: dict, seconds: float, workdir: Path,
                   overrides: list[str] = ()) -> tuple[dict[str, list[float]], str]:
    """For the camera graph with ``source`` as its RGB-D source node: per camera frame, the time
    from its camera info reaching a subscriber here to the first ``/spv/frame`` built from it
    (``source_stamp`` = the frame's stamp) reaching it [ms] (key "phosphenes"), and to the scene
    structure and the odometry pose of that frame ("scene", "pose"). Arrival times on one
    clock, so a recording's own stamps (the replay node keeps them) do not matter."""
    import yaml
    from geometry_msgs.msg import PoseStamped
    from raspv_msgs.msg import PhospheneFrame
    from raspv_msgs.msg import SceneStructure as SceneStructureMsg
    from sensor_msgs.msg import CameraInfo

    from raspv_bringup.graph import CONFIG_DIR
    from raspv_bringup.testing import Probe, RunningGraph
    from raspv_common import topics
    from raspv_common.conversions import stamp_to_seconds

    spec = yaml.safe_load((CONFIG_DIR / "camera.yaml").read_text())
    spec["launch"]["nodes"] = [source["entry"]] + [n for n in spec["launch"]["nodes"] if n["kind"] != "camera"]
    spec.pop("camera", None)
    spec.update(source["params"])
    spec.setdefault("bridge", {"ros__parameters": {}})["ros__parameters"].update({"port": 0, "tcp_port": -1})
    graph = RunningGraph(spec, workdir, list(overrides))
    probe = Probe("camera_bench")
    try:
        frames = probe.subscribe(topics.SPV_FRAME, PhospheneFrame)
        infos = probe.subscribe(topics.CAMERA_INFO, CameraInfo)
        scenes = probe.subscribe(topics.SCENE_STRUCTURE, SceneStructureMsg)
        poses = probe.subscribe(topics.CAMERA_POSE, PoseStamped)
        collectors = {"info": infos, "frames": frames, "scenes": scenes, "poses": poses}
        outputs = {"phosphenes": ("frames", lambda m: m.source_stamp),
                   "own scene": ("frames", lambda m: m.source_stamp if m.scene_stamp == m.source_stamp else None),
                   "scene": ("scenes", lambda m: m.header.stamp), "pose": ("poses", lambda m: m.header.stamp)}
        deadline = time.monotonic() + 120
        while True:                  # the first phosphene frame built from a camera frame; or the graph failed
            try:
                frames.wait(1, timeout=1.0, predicate=lambda m: stamp_to_seconds(m.source_stamp) > 0)
                break
            except TimeoutError:
                if not graph.running() or time.monotonic() > deadline:
                    raise GraphFailed(graph.output[-2000:]) from None
        for c in collectors.values():
            with c._cond:
                c.messages.clear(), c.stamps.clear()
        cpu0, t0, ticks0 = graph.cpu_by_kind(), time.monotonic(), graph.machine_ticks()
        time.sleep(seconds)
        cpu = (RunningGraph.cpu_share(cpu0, graph.cpu_by_kind(), time.monotonic() - t0) + "; "
               + RunningGraph.machine_share(ticks0, graph.machine_ticks()))
        snapshot = {}
        for name, c in collectors.items():
            with c._cond:
                snapshot[name] = list(zip(c.messages, c.stamps))
        result = {}
        for name, (collected, stamp_of) in outputs.items():
            events = sorted([(t, 0, stamp_to_seconds(m.header.stamp)) for m, t in snapshot["info"]]
                            + [(t, 1, stamp_to_seconds(stamp_of(m))) for m, t in snapshot[collected]
                               if stamp_of(m) is not None])
            # in arrival order: a frame's latency is from its (latest) arrival to the first
            # output built from it (a looping bag repeats its stamps: each pass counts anew)
            waiting: dict[float, float] = {}
            lat = []
            for t, kind, stamp in events:
                if kind == 0:
                    waiting[stamp] = t
                elif stamp in waiting:
                    lat.append(1e3 * (t - waiting.pop(stamp)))
            result[name] = lat
        result["camera frames"] = [float(len(snapshot["info"]))]
        # frames shown twice, carried then with their own scene: how many phosphenes changed level
        first_carried: dict[float, np.ndarray] = {}
        changed = []
        for m, _ in snapshot["frames"]:
            source, scene = stamp_to_seconds(m.source_stamp), stamp_to_seconds(m.scene_stamp)
            if 0 < scene != source and source not in first_carried:     # (0: no scene, a fallback frame)
                first_carried[source] = np.asarray(m.levels)
            elif scene == source and source in first_carried:
                changed.append(100.0 * float(np.mean(first_carried.pop(source) != np.asarray(m.levels))))
        result["changed"] = changed
        result["scene core"] = [float(m.processing_ms) for m, _ in snapshot["scenes"]]
        return result, graph.output + f"\nCPU (of one core): {cpu}"
    finally:
        probe.close()
        graph.stop()


def part2(recordings: dict[str, Path], args, workdir: Path) -> bool:
    """Part 2 for each source; False when a graph failed (its output is printed)."""
    from raspv_bringup.testing import claim_private_domain

    claim_private_domain()
    print(f"part 2: camera graph (config/camera.yaml), chess_floor on the optimist preset, {args.seconds:g} s each"
          + (f" [{' '.join(args.set)}]" if args.set else ""))
    cases = [("camera node, RealSense .db3", {"entry": {"kind": "camera"},
                                              "params": {"camera": {"ros__parameters": {"file": str(recordings["realsense"])}}}})]
    if not args.no_peer:
        cases.append(("peer: replay node, RASPV bag", {"entry": {"kind": "replay"}, "params": {"replay": {"ros__parameters": {
            "bag": str(recordings["bag"]), "loop": True,
            "exclude_topics": ["/camera/pose", "/spv/image", "/spv/frame", "/spv/map", "/scene/structure"]}}}}))
    failed = False
    for name, source in cases:
        try:
            result, log = _graph_latency(source, args.seconds, workdir, args.set)
        except GraphFailed as exc:
            print(f"  {name:30s} no phosphene frame from a camera frame; the graph's output ends:\n{exc}")
            failed = True
            continue
        lat = result["phosphenes"]
        verdict = ""
        if lat:
            p95 = float(np.percentile(lat, 95))
            verdict = f"  ({'meets' if p95 <= E2E_TARGET_MS else 'misses'} p95 <= {E2E_TARGET_MS:g} ms)"
        sent = int(result["camera frames"][0])
        print(f"  {name:30s} {len(lat):4d} of {sent} camera frames → phosphenes: {_stats(lat)} ms{verdict}")
        for stage, what in (("own scene", "phosphenes from its own scene result"), ("scene", "scene structure"),
                            ("pose", "odometry pose")):
            print(f"  {'':30s} {len(result[stage]):4d} of {sent} camera frames → {what}: {_stats(result[stage])} ms")
        print(f"  {'':30s} scene perception's own time per frame in the graph: {_stats(result['scene core'])} ms")
        print(f"  {'':30s} {len(result['changed']):4d} frames shown carried, then with their own scene: "
              f"phosphenes that changed level {_stats(result['changed'])} %")
        print(f"  {'':30s} {log.splitlines()[-1]}")
        if not lat:
            print("    no phosphene frame came from a camera frame; graph output:\n" + log[-2000:])
    return not failed


def run(args: argparse.Namespace) -> int:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    if args.keep and Path(args.keep).exists() and (not Path(args.keep).is_dir() or any(Path(args.keep).iterdir())):
        print(f"raspv bench camera: --keep {args.keep}: not an empty directory; choose a new one")
        return 2
    with tempfile.TemporaryDirectory(prefix="raspv-camera-bench-") as tmp:
        folder = Path(args.keep) if args.keep else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        t0 = time.monotonic()
        recordings = make_recordings(folder, args.frames, args.fps)
        print(f"recordings written by the SDKs in {time.monotonic() - t0:.1f} s: "
              + ", ".join(f"{k} {v.name}" for k, v in recordings.items()))
        part1(recordings)
        if not args.no_graph and not part2(recordings, args, folder):
            return 1
    return 0
