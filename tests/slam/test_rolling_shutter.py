"""Rolling-shutter correction: keypoints a turning rolling-shutter camera saw (each row exposed
later than the one above) are moved to where the mid-frame camera sees them — within a tenth of
a pixel at 100°/s and a 30-ms readout, where they were pixels off — and a still camera's images
are left as they are; a frame's own rotation rate comes from its pose and the two before."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from raspv_common.intrinsics import CameraIntrinsics
from raspv_slam.rolling_shutter import _rotations, correct_features, correct_images, rotation_rate, skew_px

K = CameraIntrinsics(640, 480, 517.3, 516.5, 318.6, 255.3)
READOUT = 0.03


def rolling_shutter_view(points: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of points (N, 3, mid-frame camera) seen by a rolling shutter: row v exposed
    at τ(v), when the camera had turned by exp(ω τ) (fixed-point iteration on the row)."""
    u, v, _ = K.project(points)
    for _ in range(20):
        tau = ((v + 0.5) / K.height - 0.5) * READOUT
        R = _rotations(tau[:, None] * omega[None, :])                  # C_mid ← C_row
        q = np.einsum("nji,nj->ni", R, points)                         # the point in C_row
        u, v, _ = K.project(q)
    return np.column_stack([u, v]), q


def test_keypoints_of_a_turning_camera_go_back_to_the_mid_frame_view():
    rng = np.random.default_rng(1)
    points = np.column_stack([rng.uniform(-1.5, 1.5, 300), rng.uniform(-1.0, 1.0, 300), rng.uniform(1.5, 3.0, 300)])
    omega = np.radians([20.0, 100.0, 30.0])                             # a fast pan with some tilt and roll
    seen, in_row = rolling_shutter_view(points, omega)
    u, v, _ = K.project(points)
    truth = np.column_stack([u, v])
    inside = K.contains(u, v) & K.contains(seen[:, 0], seen[:, 1])
    before = np.abs(seen - truth)[inside].max()
    uv, p = correct_features(seen.astype(np.float32), in_row.astype(np.float32), seen[:, 1] + 0.5, K, omega, READOUT)
    after = np.abs(uv - truth)[inside].max()
    assert before > 5.0 and after < 0.1, (before, after)
    np.testing.assert_allclose(p[inside], points[inside], atol=1e-4)


def test_a_still_camera_is_left_as_it_is():
    K_small = K.scaled(320, 240)
    rng = np.random.default_rng(2)
    rgb = rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)
    depth = rng.uniform(0.5, 3.0, (240, 320)).astype(np.float32)
    out_rgb, out_depth = correct_images(rgb, depth, K_small, np.zeros(3), READOUT)
    np.testing.assert_array_equal(out_rgb, rgb)
    np.testing.assert_array_equal(out_depth, depth)


def _about(axis, angle):
    return Rotation.from_rotvec(np.asarray(axis, float) / np.linalg.norm(axis) * angle).as_matrix()


def test_the_rate_at_a_frame_from_its_pose_and_the_two_before():
    """A turn speeding up (angle a·t + b·t²/2 about a tilted axis, intervals of 100 and 120 ms):
    the second-order backward difference gives the rate at the last frame, where the last
    interval's mean rate describes its middle and lags by b·h/2."""
    axis, a, b = np.array([0.2, 1.0, 0.1]), 0.5, 8.0                 # rad/s, rad/s²
    stamps = [0.0, 0.12, 0.22]
    R0 = _about([1.0, 0.0, 0.3], 0.4)                               # any start
    rotations = [R0 @ _about(axis, a * t + b * t * t / 2) for t in stamps]
    truth = axis / np.linalg.norm(axis) * (a + b * stamps[-1])
    np.testing.assert_allclose(rotation_rate(stamps, rotations), truth, atol=1e-9)
    first_order = rotation_rate(stamps[1:], rotations[1:])
    np.testing.assert_allclose(np.linalg.norm(truth - first_order), b * 0.1 / 2, rtol=1e-6)


def test_the_rate_is_in_the_last_cameras_frame():
    """A camera turning at a constant rate about its own optical axis while it also pans: the rate
    comes out in the last camera's axes whatever the earlier ones were."""
    omega = np.radians([10.0, 80.0, -25.0])
    stamps = [1.0, 1.1, 1.2]
    rotations = [_rotations((t - 1.0) * omega)[0] for t in stamps]   # body rate constant: exp(ω t)
    np.testing.assert_allclose(rotation_rate(stamps, rotations), omega, atol=1e-9)
    with pytest.raises(ValueError, match="stamps must increase"):
        rotation_rate([1.0, 1.0], rotations[:2])


def test_the_skew_is_half_the_readout_times_the_image_speed():
    """At 100°/s of pan a 30-ms readout moves the top and bottom rows by f·ω·τ/2 ≈ 13.5 px from
    the middle; a still camera has none."""
    assert skew_px(np.radians([0.0, 100.0, 0.0]), READOUT, K) == pytest.approx(517.3 * np.radians(100) * 0.015)
    assert skew_px(np.radians([0.0, 0.0, 100.0]), READOUT, K) == pytest.approx(400.0 * np.radians(100) * 0.015)
    assert skew_px(np.zeros(3), READOUT, K) == 0.0


def test_a_wall_seen_while_turning_keeps_its_depth_in_the_mid_frame_camera():
    """A wall 2 m ahead of the mid-frame camera, seen by a rolling shutter panning at 100°/s: each
    row's camera is turned, so its depth readings slope across the image (by ~3 cm at the edges);
    re-sampled to the mid-frame camera the depth is the wall's 2 m again (the depth values turned
    with their rays, not only moved)."""
    K_small = K.scaled(320, 240)
    omega = np.radians([0.0, 100.0, 0.0])
    v, u = np.mgrid[0:K_small.height, 0:K_small.width].astype(np.float64)
    rays = K_small.rays(u.ravel(), v.ravel())                                   # row camera, z = 1
    R = _rotations(((v.ravel() + 0.5) / K_small.height - 0.5)[:, None] * READOUT * omega[None, :])   # mid ← row
    depth = (2.0 / np.einsum("nij,nj->ni", R, rays)[:, 2]).reshape(v.shape).astype(np.float32)
    assert np.abs(depth - 2.0).max() > 0.02
    _, out = correct_images(None, depth, K_small, omega, READOUT)
    inside = np.isfinite(out)
    assert inside.mean() > 0.9
    np.testing.assert_allclose(out[inside], 2.0, atol=2e-3)
