import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from raspv_common.pose_buffer import PoseBuffer, PoseLookupError, interpolate_pose


def pose(yaw_deg: float, x: float = 0.0, pitch_deg: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("zy", [yaw_deg, pitch_deg], degrees=True).as_matrix()
    T[0, 3] = x
    return T


def test_interpolation_matches_scipy_slerp_and_linear_translation():
    T0, T1 = pose(10, 0.0, 5), pose(100, 2.0, -20)
    oracle = Slerp([0, 1], Rotation.from_matrix([T0[:3, :3], T1[:3, :3]]))
    for s in (0.0, 0.1, 0.37, 0.5, 0.99, 1.0):
        T = interpolate_pose(T0, T1, s)
        np.testing.assert_allclose(T[:3, :3], oracle([s]).as_matrix()[0], atol=1e-9)
        assert T[0, 3] == pytest.approx(2.0 * s)


def test_nearly_equal_rotations_interpolate_smoothly():
    T0, T1 = pose(0.0), pose(0.5)
    T = interpolate_pose(T0, T1, 0.5)
    assert Rotation.from_matrix(T[:3, :3]).as_euler("zyx", degrees=True)[0] == pytest.approx(0.25, abs=1e-6)


def test_lookup_between_out_of_order_samples():
    buf = PoseBuffer()
    for t, yaw in [(1.0, 0.0), (1.2, 40.0), (1.1, 20.0)]:
        buf.add(t, pose(yaw))
    assert len(buf) == 3 and buf.span() == (1.0, 1.2)
    yaw = Rotation.from_matrix(buf.lookup(1.15)[:3, :3]).as_euler("zyx", degrees=True)[0]
    assert yaw == pytest.approx(30.0, abs=1e-6)
    assert buf.latest().stamp == 1.2


def test_lookup_outside_the_span_holds_within_tolerance_and_refuses_beyond():
    buf = PoseBuffer(max_extrapolation_s=0.05)
    with pytest.raises(PoseLookupError, match="no pose"):
        buf.lookup(0.0)
    buf.add(1.0, pose(0, 1.0))
    buf.add(2.0, pose(0, 3.0))
    assert buf.lookup(2.04)[0, 3] == 3.0
    assert buf.lookup(0.96)[0, 3] == 1.0
    with pytest.raises(PoseLookupError, match="newer"):
        buf.lookup(2.2)
    assert buf.lookup_or_none(0.5) is None


def test_history_is_bounded_and_a_time_jump_back_clears_it():
    buf = PoseBuffer(max_age_s=1.0)
    for i in range(100):
        buf.add(i * 0.1, pose(i))
    assert buf.span()[1] - buf.span()[0] <= 1.0 + 1e-9
    buf.add(2.0, pose(0))                     # a bag looped back to its start
    assert len(buf) == 1 and buf.span() == (2.0, 2.0)


def test_same_stamp_replaces_and_bad_poses_are_refused():
    buf = PoseBuffer()
    buf.add(1.0, pose(0, 1.0))
    buf.add(1.0, pose(0, 2.0))
    assert len(buf) == 1 and buf.lookup(1.0)[0, 3] == 2.0
    with pytest.raises(ValueError):
        buf.add(1.5, np.full((4, 4), np.nan))
    with pytest.raises(ValueError):
        buf.add(math.inf, pose(0))


def test_prediction_continues_the_newest_motion_and_is_bounded():
    buf = PoseBuffer()
    assert buf.predict(1.0, 0.2) is None
    a = np.eye(4)
    b = np.eye(4)
    b[:3, :3] = Rotation.from_euler("z", 10, degrees=True).as_matrix()
    b[:3, 3] = (0.1, 0.0, 0.0)
    buf.add(1.0, a)
    np.testing.assert_allclose(buf.predict(1.5, 0.2), a)          # one sample: held
    buf.add(1.1, b)
    # inside the span it is the lookup; past it, 10°/0.1 s and 1 m/s go on
    np.testing.assert_allclose(buf.predict(1.05, 0.2), buf.lookup(1.05))
    p = buf.predict(1.15, 0.2)
    assert Rotation.from_matrix(p[:3, :3]).as_euler("zyx", degrees=True)[0] == pytest.approx(15.0, abs=1e-6)
    np.testing.assert_allclose(p[:3, 3], (0.15, 0.0, 0.0), atol=1e-9)
    # at most max_ahead_s past the newest sample
    far = buf.predict(5.0, 0.2)
    assert Rotation.from_matrix(far[:3, :3]).as_euler("zyx", degrees=True)[0] == pytest.approx(30.0, abs=1e-6)
