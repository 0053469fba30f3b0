"""Rolling-shutter correction: keypoints a turning rolling-shutter camera saw (each row exposed
later than the one above) are moved to where the mid-frame camera sees them — within a tenth of
a pixel at 100°/s and a 30-ms readout, where they were pixels off — and a still camera's images
are left as they are."""
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_slam.rolling_shutter import _rotations, correct_features, correct_images

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
