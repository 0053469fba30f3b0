"""SLAM against the RGB-D odometry on TUM-format sequences: ATE/RPE (evo), frames tracked, time, memory.

For each sequence (anything ``raspv bag from-frames`` reads with ground truth, or a bag with
``/camera/pose``), the SLAM core (``raspv_slam``) and today's frame-to-frame ``RGBDOdometry``
run side by side in this process on one core (OpenCV and Open3D at one thread):

- ATE: RMSE of the translation after SE(3) alignment, and RPE over 1 s, with ``evo`` — for SLAM
  on its final trajectory (every frame relative to its keyframe after the last correction, as
  SLAM benchmarks evaluate) and on the poses it gave online, frame by frame;
- frames tracked / predicted (motion model) / relocalised / lost;
- time per frame: wall clock of ``process`` (median, p95, max) and the tracking thread's own
  CPU time (what a loaded machine inflates least), the two systems fed each frame in
  alternation; the slowest frames while the loop closer was working (does it stall tracking?);
- memory: resident-set growth during the run and the map's own size per keyframe;
- ``--split``: a map built on the first half of the sequence, saved and loaded in localisation
  mode, places the frames of the second half (share placed, first relocalisation, ATE);
- place recognition recall: for each keyframe that revisits a place (an earlier, non-recent
  keyframe within 0.3 m and 20° by the ground truth), whether one is among the database's
  candidates.

Ratios (``measure``, gated on the quick mode by tests/bench/test_bench_ratios.py, floors in
docs/claims.yaml): ``odometry_ate`` = the odometry's ATE / the SLAM's (how many times smaller
our error), ``odometry_cpu`` = the odometry's CPU per frame / the SLAM tracking thread's (below 1:
SLAM costs more; with the odometry's quiet 11.4 ms, 0.35 is the 33 ms target).

Sequences: the path arguments, else ``$RASPV_SLAM_SEQUENCES`` (paths separated by ``:``),
else ``/work/shared/data/sequences/tum_fr1_rpy`` when it exists (not in the repository).
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DEFAULT_SEQUENCE = Path("/work/shared/data/sequences/tum_fr1_rpy")
SUBSET = REPO / "tests" / "data" / "tum_fr1_rpy_subset"
FRAME_PERIOD_MS = 1000.0 / 30.0

# --quick (raspv_bench.bench_cli): a smoke run in seconds, run by tests/bench
QUICK = {"sequences": [str(SUBSET)], "frames": 30, "split": False}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("sequences", nargs="*", help="TUM-format sequence folders or bags (default: "
                        "$RASPV_SLAM_SEQUENCES, else /work/shared/data/sequences/tum_fr1_rpy)")
    parser.add_argument("--camera", help="intrinsics preset (with its distortion and rolling-shutter readout) for "
                        "frames folders (default: a folder's own intrinsics.yaml, as `raspv sim walk` writes, "
                        "else tum-fr1)")
    parser.add_argument("--frames", type=int, help="only the first N frames of each sequence")
    parser.add_argument("--every", type=int, default=1, metavar="N",
                        help="only every N-th frame (3: a 30 Hz sequence at the slam node's 10 Hz; default 1)")
    parser.add_argument("--split", action=argparse.BooleanOptionalAction, default=True,
                        help="also map the first half and localise the second (default on)")


def _sequences(args) -> list[Path]:
    if args.sequences:
        return [Path(s) for s in args.sequences]
    env = os.environ.get("RASPV_SLAM_SEQUENCES")
    if env:
        return [Path(s) for s in env.split(":") if s]
    if DEFAULT_SEQUENCE.is_dir():
        return [DEFAULT_SEQUENCE]
    raise SystemExit("raspv bench slam: no sequence; give a path or set RASPV_SLAM_SEQUENCES "
                     f"(e.g. {SUBSET})")


def _pct(values, q: float) -> float:
    return float(np.percentile(values, q)) if len(values) else float("nan")


def _rss_mb() -> float:
    import psutil

    return psutil.Process().memory_info().rss / 2**20


def run_slam(frames, intrinsics, config, slam_map=None, localisation_only=False, odometry: bool = False):
    """Run the SLAM core over ``frames`` — and, with ``odometry``, ``RGBDOdometry`` on the same
    frames in alternation (each frame to the odometry, then to SLAM); returns what was measured."""
    from raspv_perception.rgbd_odometry import OdometryConfig, RGBDOdometry
    from raspv_slam.slam_system import SlamSystem

    rss0, peak = _rss_mb(), 0.0
    slam = SlamSystem(intrinsics, config, slam_map, localisation_only)
    odo = RGBDOdometry(OdometryConfig(threads=1)) if odometry else None
    results, wall, cpu, busy = [], [], [], []
    o = {"stamps": [], "poses": [], "wall": [], "cpu": [], "tracked": 0}
    for i, f in enumerate(frames):
        if odo is not None and f.rgb is not None and f.depth is not None:
            t0, c0 = time.perf_counter(), time.thread_time()
            step = odo.process(f.rgb, f.depth, intrinsics)
            o["wall"].append(1e3 * (time.perf_counter() - t0))
            o["cpu"].append(1e3 * (time.thread_time() - c0))
            o["tracked"] += step.tracked
            o["stamps"].append(f.stamp)
            o["poses"].append(step.world_from_camera)
        lc = slam.loop_closer
        optimising = lc is not None and lc.busy
        t0, c0 = time.perf_counter(), time.thread_time()
        r = slam.process(f.stamp, f.rgb, f.depth)
        wall.append(1e3 * (time.perf_counter() - t0))
        cpu.append(1e3 * (time.thread_time() - c0))
        busy.append(optimising)
        results.append(r)
        if i % 20 == 0:
            peak = max(peak, _rss_mb() - rss0)
    stamps, poses = slam.trajectory() if not localisation_only else (None, None)
    peak = max(peak, _rss_mb() - rss0)
    slam.close()
    return {"slam": slam, "results": results, "wall": np.array(wall), "cpu": np.array(cpu), "busy": np.array(busy),
            "final": (stamps, poses), "memory_mb": peak,
            "odometry": {k: np.array(v) if isinstance(v, list) else v for k, v in o.items()}}


def place_recall(slam, gt: dict[float, np.ndarray], candidates: int) -> tuple[int, int]:
    """(revisiting keyframes with a true place among the database's candidates, revisiting keyframes)."""
    from raspv_slam.se3 import pose_distance

    m = slam.map
    ids = sorted(k for k in m.keyframes if m.keyframes[k].stamp in gt)
    hits = total = 0
    for k in ids:
        truth = gt[m.keyframes[k].stamp]
        older = [j for j in ids if j < k - slam.config.loop_exclude_recent]
        true = {j for j in older if (lambda d: d[0] <= 0.3 and d[1] <= 20.0)(pose_distance(gt[m.keyframes[j].stamp], truth))}
        if not true:
            continue
        total += 1
        found = m.places.query(m.keyframes[k].features.descriptors, candidates,
                               exclude={j for j in m.keyframes if j >= k - slam.config.loop_exclude_recent})
        hits += bool(true & {j for j, _ in found})
    return hits, total


def _errors(gt_stamps, gt_poses, stamps, poses):
    from raspv_slam.evaluation import trajectory_errors

    if stamps is None or len(stamps) < 3:
        return None
    return trajectory_errors(gt_stamps, gt_poses, stamps, poses)


def _row(name: str, e, tracked: str, wall, cpu, extra: str = "") -> None:
    ate = f"{100 * e.ate_rmse:6.2f} cm" if e else "   n/a   "
    rpe = f"{100 * e.rpe_translation:5.2f} cm {e.rpe_rotation_deg:5.2f} deg" if e else "n/a"
    print(f"  {name:<18} ATE {ate}  RPE/1s {rpe}  {tracked}  wall ms median {np.median(wall):5.1f} p95 "
          f"{_pct(wall, 95):5.1f}  cpu ms median {np.median(cpu):5.1f} p95 {_pct(cpu, 95):5.1f}{extra}")


def _camera(path: Path, given: str | None) -> str | None:
    """The preset for ``path``: the one given; none for a bag (its camera info) or a frames folder
    with its own intrinsics.yaml (a simulator walk: no Kinect distortion or rolling shutter);
    else tum-fr1 (the shared TUM sequences' folders do not name their camera)."""
    from raspv_slam.recordings import INTRINSICS_FILE

    if given is not None:
        return given
    if path.suffix or not path.is_dir() or (path / "metadata.yaml").is_file() or (path / INTRINSICS_FILE).is_file():
        return None
    return "tum-fr1"


def bench_sequence(path: Path, args) -> dict[str, float]:
    from raspv_slam.config import SlamConfig
    from raspv_slam.recordings import open_recording

    rec = open_recording(path, camera=_camera(path, args.camera))
    frames = list(rec.frames(args.frames))[::max(1, getattr(args, "every", 1))]
    gt = [(f.stamp, f.groundtruth) for f in frames if f.groundtruth is not None]
    if len(gt) < 3:
        print(f"{path}: no ground truth; skipped")
        return {}
    gt_stamps, gt_poses = np.array([t for t, _ in gt]), np.array([p for _, p in gt])
    config = SlamConfig(distortion=rec.distortion, rolling_shutter_readout=rec.rolling_shutter, threads=1)
    print(f"\n{path} ({len(frames)} frames, {rec.intrinsics.width}x{rec.intrinsics.height}, "
          f"distortion {'yes' if rec.distortion else 'no'}, rolling shutter {1e3 * rec.rolling_shutter:.0f} ms); load average "
          f"{_load()}")
    s = run_slam(frames, rec.intrinsics, config, odometry=True)
    slam = s["slam"]
    online = [(r.stamp, r.map_from_camera) for r in s["results"]
              if r.map_from_camera is not None and r.map_id == 0]          # not a new map's own frame
    e_final = _errors(gt_stamps, gt_poses, *s["final"])
    e_online = _errors(gt_stamps, gt_poses, np.array([t for t, _ in online]), np.array([p for _, p in online]))
    c = slam.counts
    n = max(1, c["frames"])
    tracked = f"tracked {100 * (c['tracked'] + c['relocalised']) / n:5.1f} %"
    o = s["odometry"]
    o["frames"] = len(o["stamps"])
    e_odo = _errors(gt_stamps, gt_poses, o["stamps"], o["poses"])
    print(f"  {'method':<18} (ATE: RMSE after SE(3) alignment; RPE: RMSE over 1 s; time per {rec.intrinsics.width}x"
          f"{rec.intrinsics.height} frame, one core)")
    _row("SLAM final", e_final, tracked, s["wall"], s["cpu"])
    _row("SLAM online", e_online, tracked, s["wall"], s["cpu"])
    _row("RGBDOdometry", e_odo, f"tracked {100 * o['tracked'] / max(1, o['frames']):5.1f} %", o["wall"], o["cpu"])
    print(f"  SLAM frames: {c['tracked']} tracked ({c['to_last_frame']} through the last frame), {c['predicted']} "
          f"predicted by the motion model, {c['relocalised']} relocalised, {c['lost']} lost, {c['loops']} with a "
          f"loop correction, {c['new_maps']} new maps, {c['merges']} merged; "
          f"{c['rolling_shutter_second_pass']} registered again at their own rolling-shutter rate")
    ratios = {}
    if e_final and e_odo:
        ratios = {"odometry_ate": e_odo.ate_rmse / e_final.ate_rmse,
                  "odometry_cpu": float(np.median(o["cpu"]) / np.median(s["cpu"]))}
        print(f"  ATE odometry / SLAM = {ratios['odometry_ate']:.1f}x; time SLAM / odometry = "
              f"{np.median(s['wall']) / np.median(o['wall']):.2f}x wall, {1 / ratios['odometry_cpu']:.2f}x cpu")
    lc = slam.loop_closer
    busy = s["wall"][s["busy"]]
    idle = s["wall"][~s["busy"]]
    if len(busy) and len(idle):
        print(f"  while the loop closer worked ({len(busy)} frames): wall ms median {np.median(busy):.1f}, max "
              f"{busy.max():.1f}; otherwise median {np.median(idle):.1f}, max {idle.max():.1f}; frames over one "
              f"period ({FRAME_PERIOD_MS:.0f} ms) past the median: {int((busy > np.median(idle) + FRAME_PERIOD_MS).sum())}"
              f" busy, {int((idle > np.median(idle) + FRAME_PERIOD_MS).sum())} idle")
    kinds = {k: sum(e.kind == k for e in slam.map.edges) for k in ("odometry", "covisibility", "loop")}
    print(f"  map: {len(slam.map)} keyframes, edges {kinds}, {len(lc.rejected)} rejected by the optimisation, "
          f"{lc.optimisations} optimisations (median {np.median(lc.busy_ms) if lc.busy_ms else 0:.0f} ms each in the "
          f"background)")
    per_kf = slam.map.nbytes / max(1, len(slam.map)) / 1024
    print(f"  memory: resident set +{s['memory_mb']:.0f} MB during the run; map {slam.map.nbytes / 2**20:.1f} MB "
          f"({per_kf:.0f} KB per keyframe)")
    hits, total = place_recall(slam, dict(gt), config.loop_candidates)
    if total:
        print(f"  place recognition: {hits}/{total} revisiting keyframes had a true place among the "
              f"{config.loop_candidates} candidates (recall {100 * hits / total:.0f} %)")
    if args.split:
        bench_split(frames, rec, config, gt_stamps, gt_poses)
    return ratios


def bench_split(frames, rec, config, gt_stamps, gt_poses) -> None:
    from raspv_slam.map_store import load_map
    from raspv_slam.results import TrackingState

    half = len(frames) // 2
    first = run_slam(frames[:half], rec.intrinsics, config)
    with tempfile.TemporaryDirectory() as tmp:
        first["slam"].save(Path(tmp) / "half")
        loc = run_slam(frames[half:], rec.intrinsics, config, load_map(Path(tmp) / "half", config), True)
    results = loc["results"]
    placed = [r for r in results if r.map_from_camera is not None and r.map_id == 0]
    first_reloc = next((i for i, r in enumerate(results) if r.state == TrackingState.RELOCALISED), None)
    e = _errors(gt_stamps, gt_poses, np.array([r.stamp for r in placed]), np.array([r.map_from_camera for r in placed]))
    when = "never" if first_reloc is None else f"frame {first_reloc} ({results[first_reloc].stamp - results[0].stamp:.2f} s)"
    c = loc["slam"].counts
    print(f"  split: map of the first {half} frames ({len(first['slam'].map)} keyframes); localisation of the other "
          f"{len(results)}: {len(placed)} placed ({100 * len(placed) / max(1, len(results)):.1f} %), first relocalised "
          f"at {when}, {c['relocalised']} relocalisations, {c['lost']} lost; "
          + (f"ATE {100 * e.ate_rmse:.2f} cm" if e else "ATE n/a")
          + f"; wall ms median {np.median(loc['wall']):.1f}")


def _load() -> str:
    return " ".join(f"{v:.1f}" for v in os.getloadavg())


def measure(args: argparse.Namespace) -> dict[str, float]:
    """Run every sequence; the ratios of the first one with ground truth."""
    import cv2

    cv2.setNumThreads(1)
    ratios: dict[str, float] = {}
    for path in _sequences(args):
        got = bench_sequence(path, args)
        ratios = ratios or got
    print(f"\nload average at the end {_load()} (on a loaded machine compare the ratios)")
    return ratios


def run(args: argparse.Namespace) -> int:
    from raspv_bench.ratios import report

    report(args, measure(args))
    return 0
