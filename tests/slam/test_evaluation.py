"""Trajectory evaluation (raspv_slam.evaluation): poses slightly off SO(3) — what chaining
thousands of float motions produces — are evaluated instead of crashing evo, and the texture
drift measures how far a map-fixed floor point moves in the world."""
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from raspv_slam.evaluation import floor_point_ahead, orthonormalised, texture_drift, trajectory_errors


def circle(n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    stamps = np.arange(n) / 30.0
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    for i, a in enumerate(np.linspace(0, 2 * math.pi, n)):
        poses[i, :3, :3] = Rotation.from_euler("zx", [a, -110.0], degrees=[False, True]).as_matrix()
        poses[i, :3, 3] = (2 * math.cos(a), 2 * math.sin(a), 1.5)
    return stamps, poses


def test_rotations_off_so3_are_evaluated_as_their_nearest_rotation():
    stamps, truth = circle()
    estimate = truth.copy()
    estimate[:, :3, 3] += np.random.default_rng(0).normal(0, 0.01, (len(truth), 3))
    skewed = estimate.copy()
    skewed[:, :3, :3] = skewed[:, :3, :3] @ (np.eye(3) + np.array([[2e-4, 1e-4, 0], [0, -1e-4, 3e-4], [0, 0, 1e-4]]))
    from evo.core import lie_algebra
    with pytest.raises(lie_algebra.LieAlgebraException):          # what evo's rotation RPE does with them
        lie_algebra.so3_log(skewed[0, :3, :3])
    fixed = orthonormalised(skewed)
    assert np.allclose(fixed[:, :3, :3] @ fixed[:, :3, :3].transpose(0, 2, 1), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(fixed[:, :3, :3]), 1.0)
    assert np.allclose(fixed[:, :3, 3], skewed[:, :3, 3])
    a = trajectory_errors(stamps, truth, stamps, estimate)
    b = trajectory_errors(stamps, truth, stamps, skewed)
    assert b.ate_rmse == pytest.approx(a.ate_rmse, rel=1e-3)
    assert 0.005 < a.ate_rmse < 0.03


def test_texture_drift_is_the_world_motion_of_a_map_fixed_point():
    stamps, truth = circle()
    offset = np.eye(4)
    offset[:3, :3] = Rotation.from_euler("z", 40, degrees=True).as_matrix()
    offset[:3, 3] = (1.0, -2.0, 0.3)
    estimate = np.linalg.inv(offset) @ truth                 # another map frame, no drift
    point = floor_point_ahead(truth[0])
    assert point[2] == pytest.approx(0.0)
    assert texture_drift(stamps, truth, stamps, estimate, stamps[0], stamps[-1], point) == pytest.approx(0, abs=1e-9)
    drifted = estimate.copy()
    drifted[-1, :3, 3] += (0.03, 0.04, 0.0)                  # the map frame slid 5 cm by the end
    assert texture_drift(stamps, truth, stamps, drifted, stamps[0], stamps[-1], point) == pytest.approx(0.05, abs=1e-9)
    with pytest.raises(ValueError, match="within"):
        texture_drift(stamps, truth, stamps, estimate, stamps[0], stamps[-1] + 1.0, point)
