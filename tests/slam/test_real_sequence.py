"""Real data: 60 frames of TUM RGB-D fr1/rpy (hand-held Kinect v1 turning fast, motion blur;
tests/data/tum_fr1_rpy_subset, provenance in its README) with motion-capture ground truth. SLAM
places every frame, its ATE (evo, SE(3) alignment) is within a few centimetres and beats the
frame-to-frame odometry run on the same frames."""
from pathlib import Path

import numpy as np
import pytest

from raspv_perception.rgbd_odometry import OdometryConfig, RGBDOdometry
from raspv_slam.config import SlamConfig
from raspv_slam.evaluation import trajectory_errors
from raspv_slam.recordings import open_recording
from raspv_slam.slam_system import SlamSystem

SUBSET = Path(__file__).resolve().parents[1] / "data" / "tum_fr1_rpy_subset"
# measured 3.4 cm (SLAM, final trajectory) and 8.3 cm (odometry, which also fails on a fifth of
# the frames at this 15 Hz rate); published SLAM on the whole sequence: about 2 cm
ATE_BOUND_M = 0.05


@pytest.fixture(scope="module")
def recording():
    rec = open_recording(SUBSET, camera="tum-fr1")
    return rec, list(rec.frames())


def test_slam_places_every_frame_of_a_fast_real_sequence_and_beats_the_odometry(recording):
    rec, frames = recording
    gt_stamps = np.array([f.stamp for f in frames])
    gt_poses = np.array([f.groundtruth for f in frames])
    with SlamSystem(rec.intrinsics, SlamConfig(distortion=rec.distortion, background=False)) as slam:
        results = [slam.process(f.stamp, f.rgb, f.depth) for f in frames]
        stamps, poses = slam.trajectory()
    assert all(r.map_from_camera is not None for r in results)
    assert slam.counts["predicted"] == 0 and slam.counts["lost"] == 0
    ours = trajectory_errors(gt_stamps, gt_poses, stamps, poses)
    odo = RGBDOdometry(OdometryConfig(threads=1))
    odo_poses = [odo.process(f.rgb, f.depth, rec.intrinsics).world_from_camera for f in frames]
    theirs = trajectory_errors(gt_stamps, gt_poses, gt_stamps, odo_poses)
    assert ours.matched == len(frames)
    assert ours.ate_rmse < ATE_BOUND_M, ours.ate_rmse
    assert ours.ate_rmse < 0.8 * theirs.ate_rmse, (ours.ate_rmse, theirs.ate_rmse)
