"""Trajectory errors the way SLAM systems are measured, with ``evo`` (no ROS).

ATE: absolute trajectory error, RMSE of the translation after an SE(3) (Umeyama, no scale)
alignment of the estimate to the ground truth, poses associated by time stamp (≤ 20 ms, TUM's
associate). RPE: relative pose error over 1 s (translation RMSE [m] and rotation RMSE [deg]),
TUM's drift measure. Trajectories: TUM text files (``t tx ty tz qx qy qz qw``, camera to world).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

MAX_DT_S = 0.02


@dataclass
class TrajectoryErrors:
    ate_rmse: float          # [m]
    ate_max: float           # [m]
    rpe_translation: float   # RMSE over 1 s [m]
    rpe_rotation_deg: float  # RMSE over 1 s [deg]
    matched: int             # estimated poses with a ground-truth partner
    aligned: np.ndarray      # (matched, 4, 4) the estimate after alignment
    reference: np.ndarray    # (matched, 4, 4) the ground truth it was compared with
    stamps: np.ndarray       # (matched,)


def _trajectory(stamps, poses):
    from evo.core.trajectory import PoseTrajectory3D

    return PoseTrajectory3D(poses_se3=[np.asarray(p, dtype=np.float64) for p in poses],
                            timestamps=np.asarray(stamps, dtype=np.float64))


def read_trajectory(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """A TUM trajectory file → (stamps (N,), poses (N, 4, 4)); ValueError with one line if unreadable."""
    from evo.tools import file_interface

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such trajectory file")
    try:
        traj = file_interface.read_tum_trajectory_file(str(path))
    except Exception as exc:  # evo raises its own FileInterfaceException, numpy ValueError, …: one line
        raise ValueError(f"{path}: not a TUM trajectory file ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None
    if traj.num_poses == 0:
        raise ValueError(f"{path}: no poses")
    return np.asarray(traj.timestamps), np.asarray(traj.poses_se3)


def write_trajectory(path: str | Path, stamps, poses) -> None:
    """Poses (N, 4, 4) camera to world → a TUM trajectory file."""
    from scipy.spatial.transform import Rotation

    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
    q = Rotation.from_matrix(poses[:, :3, :3]).as_quat()          # x y z w
    rows = np.column_stack([np.asarray(stamps, dtype=np.float64), poses[:, :3, 3], q])
    np.savetxt(path, rows, fmt=["%.6f"] + ["%.6f"] * 7, header="timestamp tx ty tz qx qy qz qw")


def trajectory_errors(gt_stamps, gt_poses, est_stamps, est_poses, max_dt_s: float = MAX_DT_S,
                      rpe_delta_s: float = 1.0) -> TrajectoryErrors:
    """ATE and RPE of an estimate against ground truth (see the module docstring)."""
    from evo.core import metrics, sync

    if len(est_stamps) < 3:
        raise ValueError(f"need at least 3 estimated poses, got {len(est_stamps)}")
    ref, est = sync.associate_trajectories(_trajectory(gt_stamps, gt_poses), _trajectory(est_stamps, est_poses),
                                           max_diff=max_dt_s)
    if ref.num_poses < 3:
        raise ValueError(f"only {ref.num_poses} estimated poses are within {max_dt_s * 1e3:.0f} ms of a ground-truth pose")
    est.align(ref, correct_scale=False)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    dt = float(np.median(np.diff(est.timestamps))) if est.num_poses > 1 else 1.0
    delta = max(1, int(round(rpe_delta_s / max(dt, 1e-6))))
    rpe_t = rpe_r = float("nan")
    if est.num_poses > delta:
        rpe = metrics.RPE(metrics.PoseRelation.translation_part, delta=delta, delta_unit=metrics.Unit.frames,
                          all_pairs=True)
        rpe.process_data((ref, est))
        rpe_t = rpe.get_statistic(metrics.StatisticsType.rmse)
        rot = metrics.RPE(metrics.PoseRelation.rotation_angle_deg, delta=delta, delta_unit=metrics.Unit.frames,
                          all_pairs=True)
        rot.process_data((ref, est))
        rpe_r = rot.get_statistic(metrics.StatisticsType.rmse)
    return TrajectoryErrors(ape.get_statistic(metrics.StatisticsType.rmse), ape.get_statistic(metrics.StatisticsType.max),
                            float(rpe_t), float(rpe_r), ref.num_poses, np.asarray(est.poses_se3),
                            np.asarray(ref.poses_se3), np.asarray(est.timestamps))


def plot_trajectories(path: str | Path, reference: np.ndarray, estimates: dict[str, np.ndarray], title: str) -> None:
    """Top view (x–y of the ground truth's frame) and height of aligned trajectories as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, side) = plt.subplots(1, 2, figsize=(11, 5), gridspec_kw={"width_ratios": [1.3, 1]})
    top.plot(reference[:, 0, 3], reference[:, 1, 3], "k-", lw=2, label="ground truth")
    side.plot(reference[:, 2, 3], "k-", lw=2, label="ground truth")
    for name, poses in estimates.items():
        top.plot(poses[:, 0, 3], poses[:, 1, 3], "-", lw=1.2, label=name)
        side.plot(poses[:, 2, 3], "-", lw=1.2, label=name)
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_aspect("equal", adjustable="datalim")
    top.set_title("top view (ground-truth frame)")
    side.set_xlabel("pose")
    side.set_ylabel("z [m]")
    side.set_title("height")
    top.legend(loc="best", fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
