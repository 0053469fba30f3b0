"""Gravity from the accelerometer: the up direction in the camera frame."""
import math

import numpy as np
import pytest

from raspv_perception.floor import angle_deg
from raspv_perception.imu_gravity import STANDARD_GRAVITY, GravityFilter

UP = np.array([0.0, -math.cos(math.radians(30)), -math.sin(math.radians(30))])   # camera looking 30° down


def test_a_camera_at_rest_gives_its_up_direction():
    f = GravityFilter()
    assert f.up() is None
    for i in range(10):
        f.add(i / 100, STANDARD_GRAVITY * UP)
    assert angle_deg(f.up(0.09), UP) < 1e-6
    assert f.up(5.0) is None                          # too old for a frame at 5 s


def test_walking_accelerations_are_rejected_or_averaged_out():
    """A head bobbing while walking: ±2 m/s² vertical at 2 Hz, ±1 m/s² sideways, sensor noise."""
    rng = np.random.default_rng(3)
    f = GravityFilter()
    t = np.arange(0, 4, 1 / 200)
    side = np.cross(UP, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    accel = (STANDARD_GRAVITY * UP[None] + 2.0 * np.sin(2 * np.pi * 2 * t)[:, None] * UP[None]
             + 1.0 * np.sin(2 * np.pi * 1 * t + 0.3)[:, None] * side[None] + rng.normal(0, 0.1, (t.size, 3)))
    for ti, a in zip(t, accel):
        f.add(ti, a)
    assert f.rejected > 0
    assert angle_deg(f.up(t[-1]), UP) < 5.0          # well inside the 15° the floor search allows


def test_bad_samples_and_time_jumps():
    f = GravityFilter(min_samples=2)
    assert not f.add(0.0, [np.nan, 0, 9.8]) and not f.add(0.0, [0, 0, 30.0]) and not f.add(0.0, [1, 2])
    f.add(10.0, [0, -9.8, 0])
    f.add(10.01, [0, -9.8, 0])
    f.add(2.0, [9.8, 0, 0])                           # a looped recording starts over
    assert f.up(2.0) is None                          # one sample since the jump
    f.add(2.01, [9.8, 0, 0])
    np.testing.assert_allclose(f.up(2.01), [1, 0, 0])
    with pytest.raises(ValueError):
        GravityFilter(time_constant=0)
