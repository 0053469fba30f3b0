"""Poses of the frames between the SLAM core's (raspv_slam.flow_tracking) on the real TUM fr1/rpy
frames (tests/data/tum_fr1_rpy_subset: 15 Hz, a hand-held Kinect turning fast, mocap truth):
the flow from a reference frame to the next two frames agrees with the mocap's motion far better
than the constant-velocity guess a display would otherwise use, and a frame of another place
gets no pose."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from raspv_bags.from_frames import CAMERA_DISTORTION, CAMERA_PRESETS, discover_frames, read_depth
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.pose_buffer import interpolate_pose
from raspv_common.rgbd_files import read_color
from raspv_slam.flow_tracking import FlowTracker
from tests.slam.conftest import motion_error
from tests.slam.pan_floor import ground_truth

DATA = Path(__file__).resolve().parents[1] / "data" / "tum_fr1_rpy_subset"



@pytest.fixture(scope="module")
def recording():
    rec = discover_frames(DATA)
    truth = ground_truth(DATA)
    frames = [(p.stamp_s, read_color(p.color), read_depth(p.depth, rec.depth_format, rec.depth_scale))
              for p in rec.pairs]
    return frames, truth


def test_flow_follows_the_real_camera_between_reference_frames(recording):
    frames, truth = recording
    K = CameraIntrinsics(640, 480, *CAMERA_PRESETS["tum-fr1"])
    flow = FlowTracker(K, CAMERA_DISTORTION["tum-fr1"])
    flow_err, guess_err, placed = [], [], 0
    # references every third frame (the node's 10 Hz of a 30 Hz camera: here 5 Hz of 15 Hz, so
    # the frames are 67 and 133 ms after their reference); the guess: the truth's motion over the
    # two references before, continued at constant velocity (what a display predicts)
    for i in range(6, len(frames) - 2, 3):
        t_ref, rgb, depth = frames[i]
        assert flow.set_reference(t_ref, rgb, depth) >= 100
        before = np.linalg.inv(truth.lookup(frames[i - 3][0])) @ truth.lookup(t_ref)     # C_{i-3} ← C_i
        for j in (i + 1, i + 2):
            t = frames[j][0]
            true_motion = np.linalg.inv(truth.lookup(t_ref)) @ truth.lookup(t)
            s = (t - t_ref) / (t_ref - frames[i - 3][0])
            guess = interpolate_pose(np.eye(4), before, s)
            result = flow.track(frames[j][1], guess)
            guess_err.append(motion_error(np.eye(4), np.linalg.inv(guess) @ true_motion)[1])
            if result.ref_from_camera is not None:
                placed += 1
                flow_err.append(motion_error(np.eye(4), np.linalg.inv(result.ref_from_camera) @ true_motion)[1])
    n = len(guess_err)
    print(f"{placed}/{n} placed; rotation error [deg] flow median {np.median(flow_err):.2f} max {max(flow_err):.2f}, "
          f"constant velocity median {np.median(guess_err):.2f} max {max(guess_err):.2f}")
    assert placed >= 0.9 * n
    assert np.median(flow_err) < 0.5 * np.median(guess_err)
    assert np.median(flow_err) < 1.0 and np.percentile(flow_err, 90) < 2.0


def test_a_frame_of_another_place_gets_no_pose(recording):
    frames, _ = recording
    K = CameraIntrinsics(640, 480, *CAMERA_PRESETS["tum-fr1"])
    flow = FlowTracker(K, CAMERA_DISTORTION["tum-fr1"])
    flow.set_reference(*frames[0])
    covered = np.full_like(frames[0][1], 12)
    assert flow.track(covered).ref_from_camera is None
    rng = np.random.default_rng(0)
    noise = rng.integers(0, 255, frames[0][1].shape, dtype=np.uint8)
    assert flow.track(noise).ref_from_camera is None
    assert FlowTracker(K).track(frames[1][1]).ref_from_camera is None          # no reference yet
