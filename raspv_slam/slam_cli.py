"""``raspv slam``: build a map from a recording, inspect a map, evaluate against ground truth.

    raspv slam build RECORDING -o MAP          # a RASPV bag or a frames folder (TUM layout, …)
    raspv slam inspect MAP -o top.png          # occupancy, keyframe trajectory, loop edges
    raspv slam evaluate RECORDING [--groundtruth GT.txt] [--map MAP] [-o plot.png]
    raspv slam align MAP --building B.yaml [--guess X Y YAW] [-o overlay.png]

RECORDING is anything ``raspv bag from-frames`` reads, or a bag. MAP is a folder, or a name in
the maps directory (``$RASPV_MAPS_DIR``, else ``~/.local/share/raspv/maps``). ``build`` anchors
the map to the floor the first time the scene perception finds one (as the ``scene`` node does
for the live ``slam`` node). ``evaluate --map`` runs in localisation mode (the map is not
changed) and reports how many frames were relocalised and how soon. ``align`` places the
map's floor occupancy on a building map (map_server YAML + PGM) and stores the transform with
the map, where the planner's ``slam_map`` parameter reads it.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="slam_command", metavar="COMMAND", required=True)
    b = sub.add_parser("build", help="build a map from a recording (bag or RGB-D frames folder)")
    _recording_arguments(b)
    b.add_argument("-o", "--output", required=True, help="map folder, or a name in the maps directory")
    b.add_argument("--trajectory", help="also write the camera trajectory (TUM format, map frame)")
    i = sub.add_parser("inspect", help="a top-down picture of a map and its summary")
    i.add_argument("map", help="map folder or name")
    i.add_argument("-o", "--output", help="PNG to write (default: only the summary)")
    e = sub.add_parser("evaluate", help="ATE/RPE of the SLAM trajectory against ground truth (evo)")
    _recording_arguments(e)
    e.add_argument("--groundtruth", help="TUM trajectory file (default: the recording's own poses)")
    e.add_argument("--map", help="localise in this saved map instead of building one")
    e.add_argument("-o", "--output", help="trajectory plot PNG")
    e.add_argument("--trajectory", help="also write the estimated trajectory (TUM format)")
    a = sub.add_parser("align", help="place a map on a building map (map_server YAML) and store the transform")
    a.add_argument("map", help="map folder or name (built with a floor: it has occupancy.yaml)")
    a.add_argument("--building", required=True, metavar="B.yaml", help="the building's map_server YAML")
    a.add_argument("--guess", type=float, nargs=3, metavar=("X", "Y", "YAW"),
                   help="rough placement of the map's origin on the building map: x, y [m], yaw [deg]")
    a.add_argument("--radius", type=float, default=2.0, help="search radius round the guess [m] (default 2)")
    a.add_argument("--yaw-range", type=float, default=30.0, metavar="DEG",
                   help="yaw searched either side of the guess [deg] (default 30)")
    a.add_argument("-o", "--output", help="PNG: the map's occupancy drawn on the building map")


def _recording_arguments(p: argparse.ArgumentParser) -> None:
    from raspv_bags.from_frames import CAMERA_PRESETS

    p.add_argument("recording", help="RASPV bag, or a folder of RGB-D frames (TUM layout, rgb/ + depth/, pairs)")
    p.add_argument("--camera", choices=sorted(CAMERA_PRESETS), help="intrinsics preset (tum-fr1 also sets its distortion)")
    p.add_argument("--intrinsics", help="YAML with fx, fy, cx, cy (or a ROS calibration file)")
    p.add_argument("--distortion", type=float, nargs="+", metavar="K", help="plumb-bob k1 k2 p1 p2 [k3]")
    p.add_argument("--rolling-shutter", type=float, metavar="SECONDS",
                   help="readout of the colour camera's rolling shutter, first to last row (default: the preset's, "
                        "tum-fr1/fr2 0.025; else 0, a global shutter)")
    p.add_argument("--frames", type=int, help="use only the first N frames")
    p.add_argument("--start", type=int, default=0, help="skip the first N frames")


def _open(args):
    from raspv_slam.recordings import open_recording, read_intrinsics

    values = read_intrinsics(args.intrinsics) if args.intrinsics else None
    return open_recording(args.recording, camera=args.camera, intrinsics=values,
                          distortion=tuple(args.distortion) if args.distortion else None,
                          rolling_shutter=args.rolling_shutter)


def _frames(rec, args):
    n = 0
    for i, f in enumerate(rec.frames()):
        if i < args.start:
            continue
        if args.frames is not None and n >= args.frames:
            return
        n += 1
        yield f


def _config(rec):
    from raspv_slam.config import SlamConfig

    return SlamConfig(distortion=rec.distortion, rolling_shutter_readout=rec.rolling_shutter)


def _progress(i: int, total: int | None, result) -> None:
    if sys.stderr.isatty() and i % 10 == 0:
        of = f"/{total}" if total else ""
        print(f"\r  frame {i}{of}: {result.state.value:<12}", end="", file=sys.stderr, flush=True)


def _run(rec, args, slam, floor: bool):
    """Feed the recording to ``slam``; anchor to the first floor found. Returns (results, ground truth)."""
    scene = None
    if floor:
        from raspv_perception.scene_config import SceneConfig
        from raspv_perception.scene_perception import ScenePerception

        scene = ScenePerception(SceneConfig())
    results, truth = [], []
    for i, f in enumerate(_frames(rec, args)):
        r = slam.process(f.stamp, f.rgb, f.depth)
        results.append(r)
        if f.groundtruth is not None:
            truth.append((f.stamp, f.groundtruth))
        if scene is not None and r.map_from_camera is not None and f.depth is not None and not slam.map.anchored:
            s = scene.process(f.depth, rec.intrinsics).structure
            if s.floor_found:
                slam.anchor_to_floor(s.floor_plane, f.stamp)
        _progress(i, rec.count, r)
    if sys.stderr.isatty():
        print(file=sys.stderr)
    return results, truth


def _summary(results, slam) -> str:
    times = np.array([r.time_ms for r in results]) if results else np.zeros(1)
    c = slam.counts
    n = max(1, c["frames"])
    return (f"{c['frames']} frames: {c['tracked']} tracked ({100 * c['tracked'] / n:.1f} %), "
            f"{c['predicted']} predicted, {c['relocalised']} relocalised, {c['lost']} lost, "
            f"{c['new_maps']} new maps, {c['merges']} merged; "
            f"{len(slam.map)} keyframes, {sum(e.kind == 'loop' for e in slam.map.edges)} loop edges; "
            f"{np.median(times):.1f} ms per frame median, {np.percentile(times, 95):.1f} ms p95")


def run_build(args) -> int:
    from raspv_slam.map_store import resolve_map_path
    from raspv_slam.slam_system import SlamSystem

    rec = _open(args)
    for note in rec.notes:
        print(f"note: {note}")
    with SlamSystem(rec.intrinsics, _config(rec)) as slam:
        results, _ = _run(rec, args, slam, floor=True)
        if not len(slam.map):
            print("raspv slam build: no frame could start a map (no depth or no features)", file=sys.stderr)
            return 1
        slam.save(args.output)
        if args.trajectory:
            from raspv_slam.evaluation import write_trajectory

            write_trajectory(args.trajectory, *slam.trajectory())
        print(_summary(results, slam))
        print(f"map {'anchored to the floor' if slam.map.anchored else 'NOT anchored (no floor seen): level first camera'}"
              f" → {resolve_map_path(args.output)}")
    return 0


def run_inspect(args) -> int:
    from raspv_slam.map_store import load_map
    from raspv_slam.map_picture import draw_map

    m = load_map(args.map)
    kinds = {k: sum(e.kind == k for e in m.edges) for k in ("odometry", "covisibility", "loop")}
    poses = m.poses()
    xyz = np.array([(m.world_from_slam @ p)[:3, 3] for p in poses.values()]).reshape(-1, 3)
    extent = xyz.max(axis=0) - xyz.min(axis=0) if len(xyz) else np.zeros(3)
    print(f"{args.map}: {len(m)} keyframes, edges {kinds}, vocabulary "
          f"{len(m.places.vocabulary) if m.places.vocabulary else 0} words, "
          f"{'anchored to the floor' if m.anchored else 'not anchored'}, keyframes span "
          f"{extent[0]:.2f} x {extent[1]:.2f} x {extent[2]:.2f} m")
    if args.output:
        draw_map(m, args.output, title=str(args.map))
        print(f"wrote {args.output}")
    return 0


def run_evaluate(args) -> int:
    from raspv_slam.evaluation import plot_trajectories, read_trajectory, trajectory_errors, write_trajectory
    from raspv_slam.results import TrackingState
    from raspv_slam.slam_system import SlamSystem

    rec = _open(args)
    if args.map:
        slam = SlamSystem.load(args.map, rec.intrinsics, _config(rec))
    else:
        slam = SlamSystem(rec.intrinsics, _config(rec))
    t0 = time.perf_counter()
    with slam:
        results, truth = _run(rec, args, slam, floor=False)
        stamps, poses = slam.trajectory() if not args.map else _localised(results)
    wall = time.perf_counter() - t0
    if args.groundtruth:
        gt_stamps, gt_poses = read_trajectory(args.groundtruth)
    elif truth:
        gt_stamps, gt_poses = np.array([t for t, _ in truth]), np.array([p for _, p in truth])
    else:
        print("raspv slam evaluate: the recording has no ground truth; give --groundtruth GT.txt", file=sys.stderr)
        return 2
    print(_summary(results, slam) + f"; {wall:.1f} s")
    if args.map:
        placed = [r for r in results if r.map_from_camera is not None]
        first = next((i for i, r in enumerate(results) if r.state == TrackingState.RELOCALISED), None)
        t_first = "never" if first is None else f"at frame {first} ({results[first].stamp - results[0].stamp:.2f} s)"
        print(f"localisation in {args.map}: {len(placed)}/{len(results)} frames placed "
              f"({100 * len(placed) / max(1, len(results)):.1f} %), first relocalised {t_first}")
    if len(stamps) < 3:
        print("raspv slam evaluate: fewer than 3 frames were placed; nothing to evaluate", file=sys.stderr)
        return 1
    e = trajectory_errors(gt_stamps, gt_poses, stamps, poses)
    print(f"ATE {100 * e.ate_rmse:.2f} cm RMSE (max {100 * e.ate_max:.1f} cm) over {e.matched} poses; "
          f"RPE over 1 s: {100 * e.rpe_translation:.2f} cm, {e.rpe_rotation_deg:.2f} deg")
    if args.trajectory:
        write_trajectory(args.trajectory, stamps, poses)
    if args.output:
        plot_trajectories(args.output, e.reference, {"SLAM": e.aligned},
                          f"{Path(args.recording).name}: ATE {100 * e.ate_rmse:.2f} cm")
        print(f"wrote {args.output}")
    return 0


def run_align(args) -> int:
    from raspv_slam.building_alignment import AlignmentGuess, AmbiguousAlignment
    from raspv_slam.building_map import ALIGNMENT_FILE, align_saved_map
    from raspv_slam.map_store import resolve_map_path

    guess = None
    if args.guess is not None:
        if args.radius <= 0 or args.yaw_range < 0:
            print("raspv slam align: --radius must be > 0 and --yaw-range >= 0", file=sys.stderr)
            return 2
        guess = AlignmentGuess(*args.guess, radius=args.radius, yaw_range_deg=args.yaw_range)
    t0 = time.perf_counter()
    try:
        a = align_saved_map(args.map, args.building, guess)
    except AmbiguousAlignment as exc:
        print(f"raspv slam align: {exc}", file=sys.stderr)
        if args.output:
            _draw_alignment(args, exc.best, "ambiguous, best")
        return 1
    print(f"building <- map: x {a.x:.3f} m, y {a.y:.3f} m, yaw {a.yaw_deg:.2f} deg; score {a.score:.3f}, "
          f"matched {a.matched:.0%}, runner-up {a.runner_up_score:.3f} ({time.perf_counter() - t0:.1f} s)")
    print(f"stored in {resolve_map_path(args.map) / ALIGNMENT_FILE} (planner parameter slam_map:={args.map})")
    if args.output:
        _draw_alignment(args, a, "aligned")
    return 0


def _draw_alignment(args, alignment, what: str) -> None:
    from raspv_common.occupancy import load_map as load_occupancy
    from raspv_slam.building_map import map_occupancy
    from raspv_slam.map_picture import draw_alignment

    draw_alignment(map_occupancy(args.map), load_occupancy(args.building), alignment, args.output,
                   title=f"{Path(str(args.map)).name} {what}")
    print(f"wrote {args.output}")


def _localised(results):
    placed = [r for r in results if r.map_from_camera is not None and r.map_id == 0]   # the map's own frame
    return np.array([r.stamp for r in placed]), np.array([r.map_from_camera for r in placed]).reshape(-1, 4, 4)


def run(args) -> int:
    from raspv_common.occupancy import MapFormatError
    from raspv_slam.building_alignment import AlignmentError
    from raspv_slam.map_store import SlamMapError
    from raspv_slam.recordings import RecordingError

    handler = {"build": run_build, "inspect": run_inspect, "evaluate": run_evaluate,
               "align": run_align}[args.slam_command]
    try:
        return handler(args)
    except (RecordingError, SlamMapError, MapFormatError, AlignmentError) as exc:
        print(f"raspv slam {args.slam_command}: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:         # bad intrinsics, unreadable ground truth, images of the wrong size
        print(f"raspv slam {args.slam_command}: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2
