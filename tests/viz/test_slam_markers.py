"""The SLAM map as markers (raspv_viz.slam_markers): keyframes where their cameras are, a viewing
tick along each optical axis, loop edges between the right keyframes, landmarks thinned."""
from __future__ import annotations

import numpy as np
import pytest

from raspv_viz.shapes import LINE_LIST, LINE_STRIP, SPHERE_LIST
from raspv_viz.slam_markers import MAX_LANDMARKS, VIEW_LENGTH, slam_markers


def camera_at(x: float, y: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]     # optical axis along the map's x
    T[:3, 3] = (x, y, 1.5)
    return T


def test_keyframes_trajectory_and_loop_edges_are_drawn_where_the_keyframes_are():
    poses = {3: camera_at(2, 0), 1: camera_at(0, 0), 7: camera_at(2, 2)}
    shapes = {(s.ns, s.id): s for s in slam_markers(poses, np.zeros((0, 3)), [(1, 7), (1, 99)], [(1, 3)])}
    centres = shapes["keyframes", 0]
    assert centres.kind == SPHERE_LIST and np.allclose(centres.points, [[0, 0, 1.5], [2, 0, 1.5], [2, 2, 1.5]])
    ticks = shapes["keyframes", 1].points
    assert shapes["keyframes", 1].kind == LINE_LIST and ticks[1] - ticks[0] == pytest.approx([VIEW_LENGTH, 0, 0])
    assert shapes["trajectory", 0].kind == LINE_STRIP and len(shapes["trajectory", 0].points) == 3
    assert np.allclose(shapes["loop_edges", 0].points, [[0, 0, 1.5], [2, 2, 1.5]])   # 99 unknown: left out
    assert np.allclose(shapes["covisibility", 0].points, [[0, 0, 1.5], [2, 0, 1.5]])
    assert ("landmarks", 0) not in shapes


def test_landmarks_are_thinned_and_non_finite_ones_left_out():
    points = np.random.default_rng(0).normal(size=(MAX_LANDMARKS * 3, 3))
    points[5] = np.nan
    [landmarks] = [s for s in slam_markers({}, points, []) if s.ns == "landmarks"]
    assert len(landmarks.points) == MAX_LANDMARKS and np.all(np.isfinite(landmarks.points))
    assert slam_markers({}, np.zeros((0, 3)), []) == []
