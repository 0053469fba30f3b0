"""Measure a SLAM map built on a simulator walk against the walk's ground truth (no ROS).

    raspv sim walk office_two_loops -o WALK
    raspv slam build WALK -o MAP --trajectory WALK/slam.txt
    raspv sim map office -o office.yaml ; raspv slam align MAP --building office.yaml
    python tools/slam_walk_report.py WALK WALK/slam.txt [--map MAP]

prints the ATE and RPE (evo, SE(3)-aligned), the floor-texture drift at every return to the
start, and — with ``--map`` holding a building alignment made on the walk's world map (whose
frame is the world frame W) — the alignment's error against the true B ← M.

The true W ← M: M is anchored below the first camera C0 (``world_from_floor_plane``: origin on
the floor under C0, x along C0's optical axis on the floor), so W ← M = W ← C0 (truth) ·
(M ← C0 (estimate))⁻¹, projected on the floor (x, y, yaw). Texture drift: the floor point the
first camera looks at, fixed in M at the start, and where the map puts it in the world at each
return (``raspv_slam.evaluation.texture_drift``).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import yaml

from raspv_slam.evaluation import (floor_point_ahead, orthonormalised, read_trajectory, texture_drift,
                                   trajectory_errors)


def world_from_map(gt_stamps, gt_poses, est_stamps, est_poses) -> np.ndarray:
    """W ← M from the first estimated pose and the ground truth at its stamp."""
    i = int(np.argmin(np.abs(gt_stamps - est_stamps[0])))
    return orthonormalised(gt_poses[i] @ np.linalg.inv(est_poses[0]))[0]


def planar(T: np.ndarray) -> tuple[float, float, float]:
    """(x, y, yaw [deg]) of a (nearly) gravity-preserving transform."""
    return float(T[0, 3]), float(T[1, 3]), math.degrees(math.atan2(T[1, 0], T[0, 0]))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("walk", help="folder written by raspv sim walk (groundtruth.txt, walk.yaml)")
    p.add_argument("trajectory", help="the SLAM trajectory (TUM, map frame: raspv slam build --trajectory)")
    p.add_argument("--map", help="the saved map (for its building alignment)")
    args = p.parse_args(argv)
    walk = Path(args.walk)
    gt_stamps, gt_poses = read_trajectory(walk / "groundtruth.txt")
    est_stamps, est_poses = read_trajectory(args.trajectory)
    meta = yaml.safe_load((walk / "walk.yaml").read_text())
    e = trajectory_errors(gt_stamps, gt_poses, est_stamps, est_poses)
    print(f"ATE {100 * e.ate_rmse:.2f} cm RMSE (max {100 * e.ate_max:.1f} cm) over {e.matched} of "
          f"{len(gt_stamps)} frames; RPE over 1 s {100 * e.rpe_translation:.2f} cm, {e.rpe_rotation_deg:.2f} deg")
    start = est_stamps[0]
    point = floor_point_ahead(gt_poses[int(np.argmin(np.abs(gt_stamps - start)))])
    epoch = float(meta.get("epoch_s", gt_stamps[0]))
    for k, t in enumerate(meta.get("loop_times_s", []), 1):
        t_return = epoch + float(t)
        if np.min(np.abs(est_stamps - t_return)) > 0.02:
            later = est_stamps[(est_stamps > t_return) & (est_stamps < t_return + 2.0)]
            if not len(later):
                print(f"return {k} at {t:.1f} s: no estimated pose (nor within 2 s after)")
                continue
            print(f"return {k} at {t:.1f} s: no estimated pose; the first one {later[0] - t_return:.2f} s later")
            t_return = later[0]
        d = texture_drift(gt_stamps, gt_poses, est_stamps, est_poses, start, t_return, point)
        print(f"return {k} to the start at {t:.1f} s: floor texture moved {100 * d:.1f} cm "
              f"(point ({point[0]:.2f}, {point[1]:.2f}) m on the floor)")
    W_M = world_from_map(gt_stamps, gt_poses, est_stamps, est_poses)
    tilt = math.degrees(math.acos(min(1.0, W_M[2, 2])))
    x, y, yaw = planar(W_M)
    print(f"true W <- M (first pose): x {x:.3f} m, y {y:.3f} m, yaw {yaw:.2f} deg (M's z off the vertical by "
          f"{tilt:.2f} deg, height {W_M[2, 3]:+.3f} m)")
    if args.map:
        from raspv_slam.building_map import load_alignment
        from raspv_slam.map_store import SlamMapError

        try:
            a = load_alignment(args.map)
        except SlamMapError as exc:
            print(f"alignment: {exc}")
            return 0
        dyaw = (a.yaw_deg - yaw + 180.0) % 360.0 - 180.0
        print(f"stored B <- M: x {a.x:.3f} m, y {a.y:.3f} m, yaw {a.yaw_deg:.2f} deg -> error "
              f"{100 * math.hypot(a.x - x, a.y - y):.1f} cm, {abs(dyaw):.2f} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
