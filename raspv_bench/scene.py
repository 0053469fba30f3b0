"""Scene perception speed: the full pipeline per 640×480 depth frame on one core (target ≤ 40 ms median).

Frames: a walk through the sim ``apartment`` (corridor → living room), the analytic synthetic
room, and the real TUM / NYU / Kinect frames of ``tests/data/rgbd``. Depth is prepared first,
then only ``ScenePerception.process`` is timed (point cloud → labels), with per-stage medians.
For comparison the same job done the PCL way with Open3D (voxel grid, normals, RANSAC
``segment_plane`` until the planes run out, DBSCAN on the rest) runs on the same frames.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from pathlib import Path

TARGET_MS = 40.0
DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "rgbd"


# --quick (raspv_bench.bench_cli): a smoke run in seconds, run by tests/bench
QUICK = {"frames": 6, "repeat": 1, "peer_frames": 1}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=int, default=60, help="frames of the apartment and synthetic walks (default 60)")
    parser.add_argument("--repeat", type=int, default=10, help="timed runs per real frame (default 10)")
    parser.add_argument("--stride", type=int, default=None, help="pixel stride (default: SceneConfig's)")
    parser.add_argument("--no-sim", action="store_true", help="skip the apartment walk (no PyBullet rendering)")
    parser.add_argument("--no-peer", action="store_true", help="skip the Open3D comparison")
    parser.add_argument("--peer-frames", type=int, default=8, help="frames per source in the comparison (default 8)")


def _pct(values: list[float], q: float) -> float:
    v = sorted(values)
    return v[min(len(v) - 1, int(round(q * (len(v) - 1))))]


def _apartment_frames(n: int):
    from raspv_sim.simulator import SimConfig, Simulation

    frames = []
    with Simulation("apartment", SimConfig(width=640, height=480)) as sim:
        steps = max(1, int(200 / max(n, 1)))
        for i in range(n * steps):
            sim.step(0.05, 0.8, 0.15 * math.sin(i / 25))
            if i % steps == 0:
                f = sim.render()
                frames.append((f.depth, f.intrinsics, f.world_from_camera))
    return frames


def _synthetic_frames(n: int):
    from raspv_camera.synthetic_scene import SyntheticRoom
    from raspv_common.intrinsics import CameraIntrinsics

    K = CameraIntrinsics.from_hfov(640, 480, 60.0)
    room = SyntheticRoom(K)
    return [(room.render(room.pose_at(0.25 * i))[1], K, None) for i in range(n)]


def _real_frames():
    from raspv_common.intrinsics import CameraIntrinsics
    from raspv_common.rgbd_files import read_depth_scaled, read_nyu_disparity

    if not DATA.is_dir():
        return {}
    k = CameraIntrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
    out = {"TUM desk": [(read_depth_scaled(DATA / "tum_depth.png", 1 / 5000), k, None)],
           "NYU basement": [(read_nyu_disparity(DATA / "nyu_depth.pgm"), k, None)]}
    kin = CameraIntrinsics(640, 480, 525.0, 525.0, 320.0, 240.0)
    out["Kinect table (3)"] = [(read_depth_scaled(p, 0.001), kin, None)
                               for p in sorted((DATA / "kinect_table").glob("*_depth.tiff"))]
    return out


def _time_ours(frames, repeat: int, config) -> tuple[list[float], dict[str, list[float]]]:
    from raspv_perception.scene_perception import ScenePerception

    perception = ScenePerception(config)
    totals: list[float] = []
    stages: dict[str, list[float]] = {}
    for _ in range(repeat):
        perception.reset()
        for depth, K, _pose in frames:
            t0 = time.perf_counter()
            perception.process(depth, K)
            totals.append(1e3 * (time.perf_counter() - t0))
            for name, ms in perception.timings.items():
                stages.setdefault(name, []).append(ms)
    return totals, stages


def open3d_pipeline(depth, K, max_planes: int = 6) -> None:
    """The PCL-style pipeline in Open3D on one frame: voxel 4 cm, normals from 16 neighbours,
    segment_plane (0.04 m, 3 points, 300 iterations) until < 5 % of the cloud or ``max_planes``,
    DBSCAN on the rest."""
    import numpy as np
    from raspv_common.native_libs import ensure_libusb

    ensure_libusb()
    import open3d as o3d

    pts = K.backproject(np.asarray(depth, dtype=np.float32)).reshape(-1, 3)
    pts = pts[np.isfinite(pts[:, 2]) & (pts[:, 2] > 0.2) & (pts[:, 2] < 8.0)]
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts.astype(np.float64)))
    cloud = cloud.voxel_down_sample(0.04)
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(16))
    rest, n0 = cloud, len(cloud.points)
    for _ in range(max_planes):
        if len(rest.points) < max(50, 0.05 * n0):
            break
        _, inliers = rest.segment_plane(0.04, 3, 300)
        rest = rest.select_by_index(inliers, invert=True)
    if len(rest.points) >= 10:
        rest.cluster_dbscan(0.05, 10)


def part_open3d(frames, config, rounds: int) -> float:
    """Ours and the Open3D pipeline over the same ``frames``, in alternation (``rounds`` passes
    each); prints the times and returns the ratio (how many times faster ours is)."""
    import open3d  # noqa: F401  (ImportError: no peer here)

    from raspv_bench.ratios import side_by_side
    from raspv_perception.scene_perception import ScenePerception

    perception = ScenePerception(config)

    def ours() -> None:
        perception.reset()
        for depth, K, _pose in frames:
            perception.process(depth, K)

    def peer() -> None:
        for depth, K, _pose in frames:
            open3d_pipeline(depth, K)

    r = side_by_side(ours, peer, rounds=rounds)
    n = len(frames)
    print(f"Open3D PCL-style pipeline on {n} of these frames, in alternation with ours: {1e3 * r.peer_s / n:.1f} ms "
          f"per frame (ours {1e3 * r.ours_s / n:.1f} ms, {r.ratio:.1f}x faster; theirs gives planes and clusters only: "
          "no floor tracking, classes, labels or free floor)")
    return r.ratio


def _time_stairs(n: int) -> None:
    """Stair detection (after scene perception) on a walk up to the stairs world's ascending
    staircase and a look down its descending one, 640×480."""
    from raspv_perception.scene_perception import ScenePerception
    from raspv_perception.stairs import StairDetector
    from raspv_sim.simulator import SimConfig, Simulation

    frames = []
    with Simulation("stairs", SimConfig(width=640, height=480)) as sim:
        for i in range(n):
            x, y, pitch = (5.8, 1.0 + 2.5 * i / n, 25.0) if i % 2 == 0 else (10.2, 3.0 + 1.5 * i / n, 45.0)
            f = sim.render_from(x, y, math.radians(90.0), head_pitch=math.radians(pitch))
            frames.append((f.depth, f.intrinsics, f.world_from_camera))
    perception, detector = ScenePerception(), StairDetector()
    times, found = [], 0
    for depth, K, pose in frames:
        structure = perception.process(depth, K, pose).structure
        t0 = time.perf_counter()
        stair = detector.detect(depth, K, structure)
        times.append((time.perf_counter() - t0) * 1e3)
        found += stair is not None
    print(f"Stair detection after scene perception, stairs world ({len(frames)} frames up and down the stairs, "
          f"640x480, stride {detector.config.stride}): median {statistics.median(times):.1f} ms, "
          f"p90 {_pct(times, 0.9):.1f} ms; staircase found in {found}/{len(frames)}")


def measure(args: argparse.Namespace) -> dict[str, float]:
    """The timings asked for, printed; the ratio against the Open3D pipeline run side by side
    (``open3d``: times faster) unless ``--no-peer`` or Open3D is missing."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")       # one core, also for Open3D (read at import)
    import cv2

    from raspv_perception.scene_config import SceneConfig

    cv2.setNumThreads(1)
    config = SceneConfig() if args.stride is None else SceneConfig(stride=args.stride)
    sources: dict[str, list] = {}
    if not args.no_sim:
        try:
            sources["sim apartment walk"] = _apartment_frames(args.frames)
        except Exception as exc:             # no renderer here: say so, time the rest
            print(f"(apartment walk skipped: {exc})")
    sources["synthetic room walk"] = _synthetic_frames(args.frames)
    real = _real_frames()
    sources.update(real)
    if not real:
        print(f"(real frames skipped: {DATA} not found)")

    print(f"Scene perception, 640x480 depth, one core (stride {config.stride}); ms per frame")
    print(f"{'frames':<22}{'n':>5}{'median':>9}{'p90':>8}{'max':>8}   stages (median ms)")
    all_totals: list[float] = []
    for name, frames in sources.items():
        repeat = 1 if len(frames) >= 20 else args.repeat
        totals, stages = _time_ours(frames, repeat, config)
        all_totals.extend(totals)
        stage_text = " ".join(f"{k}={statistics.median(v):.1f}" for k, v in stages.items())
        print(f"{name:<22}{len(totals):>5}{statistics.median(totals):>9.1f}{_pct(totals, 0.9):>8.1f}"
              f"{max(totals):>8.1f}   {stage_text}")
    median = statistics.median(all_totals)
    verdict = "meets" if median <= TARGET_MS else "MISSES"
    print(f"{'all':<22}{len(all_totals):>5}{median:>9.1f}{_pct(all_totals, 0.9):>8.1f}{max(all_totals):>8.1f}"
          f"   -> {verdict} the {TARGET_MS:.0f} ms target")
    if not args.no_sim:
        try:
            _time_stairs(args.frames)
        except Exception as exc:             # no renderer here: say so
            print(f"(stair detection skipped: {exc})")
    ratios: dict[str, float] = {}
    if not args.no_peer:
        per = max(1, args.peer_frames)
        peer_frames = [f for frames in sources.values() for f in frames[:: max(1, len(frames) // per)][:per]]
        try:
            ratios["open3d"] = part_open3d(peer_frames, config, rounds=3)
        except ImportError as exc:
            print(f"(Open3D comparison skipped: {exc})")
    return ratios


def run(args: argparse.Namespace) -> int:
    from raspv_bench.ratios import report

    from raspv_perception.scene_config import SceneConfig

    try:
        SceneConfig() if args.stride is None else SceneConfig(stride=args.stride)
    except ValueError as exc:
        print(f"raspv bench scene: {exc}")
        return 2
    report(args, measure(args))
    return 0
