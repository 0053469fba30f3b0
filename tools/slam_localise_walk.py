"""Localisation mode on a simulator walk: how soon and how well a saved map places the camera (no ROS).

    raspv sim walk office_kidnap -o KIDNAP
    python tools/slam_localise_walk.py MAP KIDNAP --reference WALK [--starts 0 12 35]

MAP was built on the walk in WALK (same world); KIDNAP is another walk in that world, with a
covered-camera kidnap (walk.yaml ``kidnaps``). The map is loaded in localisation mode
(``SlamSystem.load``, nothing written) and fed the frames one by one on this process's core:

- from each ``--starts`` time [s] (a fresh system each, no initial pose): the time to the first
  relocalisation and the pose error then;
- the whole walk from its start: frames placed, and after every kidnap the time from the moment
  the camera is uncovered to the first relocalisation, and the pose error then.

Pose error: the estimate M ← C taken to the world by the true W ← M — M sits on the floor under
the map's first keyframe camera with x along its optical axis, so W ← M = W ← C_kf0 (the
reference walk's ground truth at that keyframe's stamp) · (M ← C_kf0)⁻¹ — against W ← C.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from raspv_slam.evaluation import orthonormalised, read_trajectory


def true_world_from_map(map_path: str, reference_walk: Path) -> np.ndarray:
    from raspv_slam.map_store import load_map

    m = load_map(map_path)
    poses = m.poses()
    first = min(m.permanent, key=lambda k: m.keyframes[k].stamp)
    gt_stamps, gt_poses = read_trajectory(reference_walk / "groundtruth.txt")
    i = int(np.argmin(np.abs(gt_stamps - m.keyframes[first].stamp)))
    if abs(gt_stamps[i] - m.keyframes[first].stamp) > 0.02:
        raise SystemExit(f"{reference_walk}: no ground truth at the map's first keyframe; is it the walk the map was built on?")
    return orthonormalised(gt_poses[i] @ np.linalg.inv(m.world_from_slam @ poses[first]))[0]


def pose_error(world_from_map: np.ndarray, map_from_camera: np.ndarray, world_from_camera: np.ndarray):
    e = np.linalg.inv(world_from_camera) @ world_from_map @ map_from_camera
    angle = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(orthonormalised(e)[0][:3, :3]) - 1) / 2))))
    return float(np.linalg.norm(e[:3, 3])), angle


def run(map_path: str, walk: Path, start_s: float, stop_after_s: float | None, frames: int | None = None):
    """Feed ``walk`` from ``start_s`` [s into it] to a fresh localisation system. Returns a list of
    (stamp, state, map_from_camera, groundtruth, ms)."""
    from raspv_slam.recordings import open_recording
    from raspv_slam.results import TrackingState
    from raspv_slam.slam_system import SlamSystem

    rec = open_recording(walk)
    out = []
    t_first = None
    with SlamSystem.load(map_path, rec.intrinsics) as slam:
        t0 = None
        for f in rec.frames():
            t0 = f.stamp if t0 is None else t0
            if f.stamp - t0 < start_s - 1e-6:
                continue
            if frames is not None and len(out) >= frames:
                break
            r = slam.process(f.stamp, f.rgb, f.depth)
            out.append((f.stamp, r.state, r.map_from_camera, f.groundtruth, r.time_ms))
            if r.state == TrackingState.RELOCALISED and t_first is None:
                t_first = f.stamp
            if stop_after_s is not None and t_first is not None and f.stamp - t_first > stop_after_s:
                break
    return out


def first_relocalisation(results, after: float, W_M):
    from raspv_slam.results import TrackingState

    for stamp, state, M_C, gt, _ in results:
        if stamp >= after and state == TrackingState.RELOCALISED:
            return stamp - after, pose_error(W_M, M_C, gt)
    return None


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("map", help="saved SLAM map (folder or name)")
    p.add_argument("walk", type=Path, help="the walk to localise (raspv sim walk folder)")
    p.add_argument("--reference", type=Path, required=True, help="the walk the map was built on (its ground truth)")
    p.add_argument("--starts", type=float, nargs="*", default=[], help="also start fresh at these times [s]")
    p.add_argument("--frames", type=int, help="feed only this many frames of the whole walk")
    args = p.parse_args(argv)
    meta = yaml.safe_load((args.walk / "walk.yaml").read_text())
    W_M = true_world_from_map(args.map, args.reference)
    print(f"load average {' '.join(f'{v:.1f}' for v in os.getloadavg())}")
    for s in args.starts:
        results = run(args.map, args.walk, s, stop_after_s=0.5)
        got = first_relocalisation(results, results[0][0], W_M)
        print(f"start at {s:.1f} s: " + ("never relocalised" if got is None else
              f"relocalised after {got[0]:.2f} s, error {100 * got[1][0]:.1f} cm, {got[1][1]:.2f} deg"))
    t = time.perf_counter()
    results = run(args.map, args.walk, 0.0, None, args.frames)
    wall = time.perf_counter() - t
    t0 = results[0][0]
    placed = [r for r in results if r[2] is not None]
    errors = np.array([pose_error(W_M, r[2], r[3]) for r in placed])
    ms = np.array([r[4] for r in results])
    got = first_relocalisation(results, t0, W_M)
    print(f"whole walk: {len(placed)}/{len(results)} frames placed; from the start relocalised "
          + ("never" if got is None else f"after {got[0]:.2f} s, error {100 * got[1][0]:.1f} cm, {got[1][1]:.2f} deg"))
    for k in meta.get("kidnaps", []):
        uncovered = t0 + float(k["at_s"]) + float(k["covered_s"])
        got = first_relocalisation(results, uncovered - 1e-6, W_M)
        print(f"kidnap at {k['at_s']:.1f} s, covered {k['covered_s']:.1f} s: " + ("never relocalised" if got is None else
              f"relocalised {got[0]:.2f} s after the camera was uncovered, error {100 * got[1][0]:.1f} cm, "
              f"{got[1][1]:.2f} deg"))
    if len(errors):
        print(f"pose error of placed frames: median {100 * np.median(errors[:, 0]):.1f} cm / "
              f"{np.median(errors[:, 1]):.2f} deg, p95 {100 * np.percentile(errors[:, 0], 95):.1f} cm / "
              f"{np.percentile(errors[:, 1], 95):.2f} deg")
    print(f"time per frame: median {np.median(ms):.1f} ms, p95 {np.percentile(ms, 95):.1f} ms; {wall:.0f} s wall")
    return 0


if __name__ == "__main__":
    sys.exit(main())
