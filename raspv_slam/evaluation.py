"""Trajectory errors the way SLAM systems are measured, with ``evo`` (no ROS).

ATE: absolute trajectory error, RMSE of the translation after an SE(3) (Umeyama, no scale)
alignment of the estimate to the ground truth, poses associated by time stamp (≤ 20 ms, TUM's
associate). RPE: relative pose error over 1 s (translation RMSE [m] and rotation RMSE [deg]),
TUM's drift measure. Trajectories: TUM text files (``t tx ty tz qx qy qz qw``, camera to world).
Rotations are re-orthonormalised (nearest rotation, SVD) before evo sees them: a pose chained
over thousands of frames in float arithmetic drifts off SO(3) by more than evo's check allows.

Texture drift (:func:`texture_drift`): how far a point fixed in the SLAM map (a Chess-Floor
texture's corner) moves in the world between two moments — the user's view of drift.
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


def orthonormalised(poses) -> np.ndarray:
    """Poses (N, 4, 4) with each rotation block replaced by the nearest rotation matrix (SVD,
    determinant +1); translations unchanged."""
    out = np.array(poses, dtype=np.float64).reshape(-1, 4, 4)
    u, _, vt = np.linalg.svd(out[:, :3, :3])
    flip = np.where(np.linalg.det(u @ vt) < 0, -1.0, 1.0)
    u[:, :, 2] *= flip[:, None]
    out[:, :3, :3] = u @ vt
    out[:, 3] = (0.0, 0.0, 0.0, 1.0)
    return out


def _trajectory(stamps, poses):
    from evo.core.trajectory import PoseTrajectory3D

    return PoseTrajectory3D(poses_se3=list(orthonormalised(poses)),
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

    poses = orthonormalised(poses)
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


def _pose_at(stamps: np.ndarray, poses: np.ndarray, t: float, max_dt_s: float) -> np.ndarray:
    i = int(np.argmin(np.abs(stamps - t)))
    if abs(stamps[i] - t) > max_dt_s:
        raise ValueError(f"no pose within {max_dt_s * 1e3:.0f} ms of t = {t:.3f} s")
    return poses[i]


def texture_drift(gt_stamps, gt_poses, est_stamps, est_poses, t_start: float, t_return: float,
                  world_point, max_dt_s: float = MAX_DT_S) -> float:
    """How far [m] a point fixed in the estimate's map frame M moves in the world W between
    ``t_start`` and ``t_return`` [s]: the point is ``world_point`` (W, e.g. the floor point the
    camera looks at when it starts) as placed at ``t_start``. At time t a map point q is drawn
    where the world holds W ← C(t) · (M ← C(t))⁻¹ · q (truth times the inverse estimate), so a
    drift-free map keeps it still. Poses: W ← C (ground truth) and M ← C (estimate)."""
    gt_stamps, est_stamps = np.asarray(gt_stamps, float), np.asarray(est_stamps, float)
    gt_poses, est_poses = orthonormalised(gt_poses), orthonormalised(est_poses)

    def world_from_map(t: float) -> np.ndarray:
        return _pose_at(gt_stamps, gt_poses, t, max_dt_s) @ np.linalg.inv(_pose_at(est_stamps, est_poses, t, max_dt_s))

    p = np.append(np.asarray(world_point, float), 1.0)
    q = np.linalg.inv(world_from_map(t_start)) @ p
    return float(np.linalg.norm((world_from_map(t_return) @ q)[:3] - p[:3]))


def floor_point_ahead(world_from_camera: np.ndarray, floor_z: float = 0.0) -> np.ndarray:
    """Where the optical axis of W ← C meets the floor z = ``floor_z`` (W, z up); ValueError if
    the camera does not look down."""
    T = np.asarray(world_from_camera, float)
    origin, axis = T[:3, 3], T[:3, 2]
    if axis[2] >= -1e-6:
        raise ValueError("the camera does not look at the floor")
    return origin + axis * (floor_z - origin[2]) / axis[2]


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
