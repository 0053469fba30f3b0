"""Dynamic Window Approach: heading, clearance, speed, braking admissibility; measured velocity."""
import math

import numpy as np
import pytest

from raspv_nav.local_planner import DWAConfig, DWAPlanner, lookahead_point
from raspv_nav.motion import MapAlignment, VelocityEstimator, planar_pose, planar_transform

STRAIGHT = np.array([[0.0, 0.0], [6.0, 0.0]])


def wall_at(x, half_width=0.6):
    return np.array([[x, y] for y in np.linspace(-half_width, half_width, 25)])


def test_goes_straight_at_speed_when_free():
    dwa = DWAPlanner()
    r = dwa.command((0.0, 0.0, 0.0), (0.7, 0.0), STRAIGHT, np.empty((0, 2)))
    assert r.feasible and r.linear == pytest.approx(0.8) and abs(r.angular) < 0.05
    np.testing.assert_allclose(r.target, [dwa.config.lookahead, 0.0])


def test_speeds_stay_in_the_dynamic_window_around_the_measured_velocity():
    c = DWAConfig()
    dwa = DWAPlanner(c)
    r = dwa.command((0.0, 0.0, 0.0), (0.0, 0.0), STRAIGHT, np.empty((0, 2)))
    assert r.linear == pytest.approx(c.max_accel * c.control_period)     # from standing: one step of acceleration
    r = dwa.command((0.0, 0.0, 0.0), (0.0, 0.0), np.array([[0.0, 0.0], [0.0, 5.0]]), np.empty((0, 2)))
    assert r.angular == pytest.approx(c.max_turn_accel * c.control_period)   # turn left towards +y, within the window


def test_swerves_around_an_obstacle_on_a_bent_path():
    dwa = DWAPlanner()
    wall = wall_at(1.2, 0.3)
    around = np.array([[0.0, 0.0], [1.2, 0.9], [2.4, 0.0], [6.0, 0.0]])
    r = dwa.command((0.0, 0.0, 0.0), (0.6, 0.0), around, wall)
    assert r.feasible and r.angular > 0.2
    assert np.linalg.norm(r.trajectory[:, None] - wall[None], axis=2).min() > dwa.config.robot_radius


def test_braking_admissibility_slows_down_before_a_wall():
    """At 0.8 m/s a wall 0.6 m ahead (0.3 m before the robot radius touches it) leaves too
    little room to brake at full speed (0.29 m with the reaction time): only slower commands are
    admissible (v²/2a + v·period ≤ dist)."""
    c = DWAConfig(max_turn=0.05, samples_w=3)           # no room to steer: it must brake
    dwa = DWAPlanner(c)
    r = dwa.command((0.0, 0.0, 0.0), (0.8, 0.0), STRAIGHT, wall_at(0.6, 2.0))
    assert r.feasible
    assert r.linear < 0.8 - 1e-6
    dist = 0.6 - c.robot_radius
    assert r.linear ** 2 / (2 * c.max_accel) + r.linear * c.control_period <= dist
    far = dwa.command((0.0, 0.0, 0.0), (0.8, 0.0), STRAIGHT, wall_at(3.5, 2.0))
    assert far.linear == pytest.approx(0.8)               # the same wall far away: no need to brake


def test_boxed_in_it_brakes_and_near_a_wall_it_can_still_move_away():
    dwa = DWAPlanner()
    ring = np.array([[math.cos(a) * 0.4, math.sin(a) * 0.4] for a in np.linspace(0, 2 * math.pi, 90)])
    boxed = dwa.command((0.0, 0.0, 0.0), (0.5, 0.0), STRAIGHT, ring)
    assert boxed.linear < 0.5                              # braking, never speeding into it
    touching = np.array([[-0.2, y] for y in np.linspace(-1, 1, 41)])   # a wall 0.2 m behind
    away = dwa.command((0.0, 0.0, 0.0), (0.0, 0.0), STRAIGHT, touching)
    assert away.feasible and away.linear > 0


def test_lookahead_point_follows_the_path():
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    np.testing.assert_allclose(lookahead_point(path, np.array([1.0, 0.1]), 1.5), [2.0, 0.5])
    np.testing.assert_allclose(lookahead_point(path, np.array([0.0, 0.0]), 10.0), [2.0, 2.0])


def test_velocity_from_successive_poses():
    est = VelocityEstimator(window_s=0.3)
    assert est.velocity() == (0.0, 0.0)
    for i in range(10):                                   # an arc: 0.5 m/s, 0.4 rad/s
        t = 100.0 + 0.05 * i
        yaw = 0.4 * (t - 100.0)
        x = 0.5 / 0.4 * math.sin(yaw)
        y = 0.5 / 0.4 * (1 - math.cos(yaw))
        est.add(t, x, y, yaw)
    v, w = est.velocity()
    assert v == pytest.approx(0.5, rel=0.02) and w == pytest.approx(0.4, rel=1e-6)
    est.add(50.0, 0.0, 0.0, 0.0)                          # the bag looped: start again
    assert est.velocity() == (0.0, 0.0)


def test_planar_pose_and_map_alignment():
    T = planar_transform(1.0, 2.0, math.radians(30))
    assert planar_pose(T) == pytest.approx((1.0, 2.0, math.radians(30)))
    a = MapAlignment((10.0, 5.0, math.radians(90)))      # odometry origin at (10, 5) of the map, x along map y
    np.testing.assert_allclose(a.points_to_map([[1.0, 0.0]]), [[10.0, 6.0]], atol=1e-12)
    np.testing.assert_allclose(a.points_to_world(a.points_to_map([[0.3, -2.0]])), [[0.3, -2.0]], atol=1e-12)
    assert a.yaw_to_world(math.radians(90)) == pytest.approx(0.0)
