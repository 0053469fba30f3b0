"""The route a virtual patient plans on what it saw (perceived_map.plan_route) and the floor patch
it remembers for an obstacle's base (navigate_policy.footprints)."""
from __future__ import annotations

import math

import numpy as np

from raspv_experiments.navigate_policy import footprints
from raspv_experiments.perceived_map import plan_route
from raspv_experiments.policies import PhospheneLayout, PolicyConfig


def wall(x: float, y0: float, y1: float) -> np.ndarray:
    """Floor points [m] of an obstacle across the way at ``x`` from ``y0`` to ``y1``."""
    ys = np.arange(y0, y1 + 1e-9, 0.05)
    return np.column_stack([np.full(len(ys), x), ys])


def test_nothing_seen_the_route_goes_straight_to_a_far_goal():
    route = plan_route(np.zeros(2), np.array([20.0, 0.0]), np.empty((0, 2)), 0.25, 0.7)
    assert route.reachable
    assert np.abs(route.points[:, 1]).max() < 0.06 and route.points[-1, 0] > 1.5    # ahead, 2 m of it


def test_the_route_goes_round_an_obstacle_on_its_shorter_side():
    seen = wall(1.5, -0.8, 0.3)                                   # reaches further to the right (y < 0)
    route = plan_route(np.zeros(2), np.array([6.0, 0.0]), seen, 0.25, 0.7, length=3.0)
    assert route.reachable
    at = route.points[np.argmin(np.abs(route.points[:, 0] - 1.5))]
    assert at[1] > 0.3 + 0.25                                      # passes left of it, clear of the body radius


def test_a_side_once_taken_is_kept_unless_the_other_is_clearly_shorter():
    seen = wall(1.5, -0.3, 0.3)                                    # symmetric: both ways equally long
    right = plan_route(np.zeros(2), np.array([6.0, 0.0]), seen, 0.25, 0.7, keep=np.array([0.7, -0.5]))
    left = plan_route(np.zeros(2), np.array([6.0, 0.0]), seen, 0.25, 0.7, keep=np.array([0.7, 0.5]))
    assert right.points[-1, 1] < -0.3 and left.points[-1, 1] > 0.3
    lopsided = wall(1.5, -2.5, 0.3)                                # now the right is far longer
    switched = plan_route(np.zeros(2), np.array([6.0, 0.0]), lopsided, 0.25, 0.7, keep=np.array([0.7, -0.5]))
    assert switched.points[-1, 1] > 0.3


def test_walled_in_there_is_no_route():
    ring = np.array([(2.0 * math.cos(a), 2.0 * math.sin(a)) for a in np.linspace(0, 2 * math.pi, 400)])
    assert not plan_route(np.zeros(2), np.array([6.0, 0.0]), ring, 0.25, 0.7).reachable


def test_a_goal_on_an_obstacle_is_reached_beside_it():
    bin_ = np.array([(3.0 + dx, dy) for dx in (-0.1, 0.0, 0.1) for dy in (-0.1, 0.0, 0.1)])
    route = plan_route(np.zeros(2), np.array([3.0, 0.0]), bin_, 0.25, 0.7, length=5.0)
    assert route.reachable and np.hypot(*(route.points[-1] - [3.0, 0.0])) <= 0.6 + 0.08


def grid_layout(n: int, size: int = 400, fov_deg: float = 35.0) -> PhospheneLayout:
    c = (np.arange(n) + 0.5) * size / n
    x, y = np.meshgrid(c, c)
    return PhospheneLayout(x.ravel(), y.ravel(), size, size, size / (2 * math.tan(math.radians(fov_deg) / 2)))


def test_a_coarse_phosphene_leaves_a_patch_a_fine_one_a_point():
    config = PolicyConfig(head_pitch_deg=40.0, eye_height=1.6)
    extent = {}
    for n in (4, 50):
        layout = grid_layout(n)
        ground, owner = footprints(layout, config)
        i = int(np.argmin(np.hypot(layout.x - 200, layout.y - 0.75 * 400)))      # below the centre
        patch = ground[owner == i]
        assert len(patch) and np.isfinite(patch).all()
        extent[n] = (np.ptp(patch[:, 0]), np.ptp(patch[:, 1]))
    assert extent[4][0] > 0.3 and extent[4][1] > 0.2                # about 0.5 m deep, 0.3 m across
    assert extent[50][0] < 0.1 and extent[50][1] < 0.05
