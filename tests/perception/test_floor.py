"""Floor frame, camera angles and the floor tracker."""
import math

import numpy as np
import pytest

from raspv_perception.floor import (FloorCandidate, FloorTracker, camera_angles, floor_frame, transform_plane)
from raspv_perception.scene_config import SceneConfig


def floor_plane(pitch_deg: float, roll_deg: float, height: float) -> np.ndarray:
    """Floor seen by a camera pitched down and rolled (right side lower) at ``height``."""
    p, r = math.radians(pitch_deg), math.radians(roll_deg)
    down = np.array([math.sin(r) * math.cos(p), math.cos(r) * math.cos(p), math.sin(p)])
    return np.array([*(-down), height])


def test_floor_frame_follows_the_convention():
    plane = floor_plane(25.0, 4.0, 1.55)
    T = floor_frame(plane)
    R, t = T[:3, :3], T[:3, 3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[:, 1], -plane[:3], atol=1e-12)            # y_F along gravity
    assert plane[:3] @ t + plane[3] == pytest.approx(0.0, abs=1e-12)      # origin on the floor ...
    np.testing.assert_allclose(np.cross(t, plane[:3]), 0, atol=1e-12)     # ... right below the camera
    z = R[:, 2]
    # the optical axis projected on the floor is z_F
    proj = np.array([0, 0, 1.0]) - (np.array([0, 0, 1.0]) @ R[:, 1]) * R[:, 1]
    np.testing.assert_allclose(z, proj / np.linalg.norm(proj), atol=1e-12)
    # a floor point in F has y = 0; the camera centre is at height 1.55 (y = -1.55)
    F_from_C = np.linalg.inv(T)
    assert (F_from_C @ [0, 0, 0, 1])[1] == pytest.approx(-1.55)


def test_camera_angles_signs():
    pitch, roll = camera_angles(floor_plane(30.0, -6.0, 1.6))
    assert pitch == pytest.approx(30.0) and roll == pytest.approx(-6.0)
    pitch, _ = camera_angles(floor_plane(-5.0, 0.0, 1.6))
    assert pitch == pytest.approx(-5.0)       # looking up


def test_first_floor_limits_and_tracking():
    cfg = SceneConfig()
    tracker = FloorTracker(cfg)
    expect = tracker.expectation(None)
    too_low = FloorCandidate(floor_plane(20, 0, 0.7), 3.0)
    too_tilted = FloorCandidate(floor_plane(50, 0, 1.5), 3.0)
    too_small = FloorCandidate(floor_plane(20, 0, 1.5), 0.2)
    good = FloorCandidate(floor_plane(20, 0, 1.5), 3.0)
    assert tracker.choose([too_low, too_tilted, too_small], expect) is None
    assert tracker.choose([too_low, good], expect) is good
    tracker.update(good.plane, None)
    expect = tracker.expectation(None)
    # tracked: a 0.05 m / 10° change is the floor, a 0.15 m step is not
    near = FloorCandidate(floor_plane(30, 0, 1.55), 2.0)
    step = FloorCandidate(floor_plane(20, 0, 1.35), 2.0)
    assert tracker.choose([step, near], expect) is near
    assert tracker.choose([step], expect) is None
    # once tracking, a low camera that would fail the first-floor limits is still followed
    for h in (1.45, 1.38, 1.31, 1.24, 1.17, 1.10, 1.03, 0.96):
        c = FloorCandidate(floor_plane(20, 0, h), 2.0)
        assert tracker.choose([c], tracker.expectation(None)) is c
        tracker.update(c.plane, None)


def test_track_is_dropped_after_missed_frames():
    cfg = SceneConfig(track_lost_frames=3)
    tracker = FloorTracker(cfg)
    tracker.update(floor_plane(20, 0, 1.5), None)
    for _ in range(2):
        tracker.update(None, None)
        assert tracker.tracking
    tracker.update(None, None)
    assert not tracker.tracking
    assert tracker.expectation(None).max_angle_deg == cfg.first_floor_max_angle_deg


def test_pose_prior_and_tracking_with_poses():
    tracker = FloorTracker(SceneConfig())
    # camera at 1.6 m looking down 60°: world z up seen from the camera
    p = math.radians(60)
    # W <- C: optical z forward (world y) and 60° down, x along world x
    z_c = np.array([0, math.cos(p), -math.sin(p)])      # optical axis in W
    x_c = np.array([1.0, 0, 0])
    y_c = np.cross(z_c, x_c)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x_c, y_c, z_c], axis=1)
    pose[:3, 3] = [0, 0, 1.6]
    expect = tracker.expectation(pose)
    up_c = pose[:3, :3].T @ [0, 0, 1]
    np.testing.assert_allclose(expect.up, up_c)
    assert expect.max_angle_deg == SceneConfig().prior_max_angle_deg
    floor_c = transform_plane(np.array([0, 0, 1.0, 0.0]), np.linalg.inv(pose))
    assert floor_c[3] == pytest.approx(1.6)
    cand = FloorCandidate(floor_c, 3.0)
    assert tracker.choose([cand], expect) is cand
    tracker.update(floor_c, pose)
    # the camera moves 1 m forward and turns: the prediction follows the pose
    pose2 = pose.copy()
    pose2[:3, 3] = [0.3, 1.0, 1.62]
    predicted = tracker.expectation(pose2).predicted
    np.testing.assert_allclose(predicted, transform_plane(np.array([0, 0, 1.0, 0.0]), np.linalg.inv(pose2)), atol=1e-12)
