"""Stair detection core (paper §III-D1): staircases of the sim ``stairs`` world measured from
depth renders (riser 0.17 m, tread 0.29 m, width 1.4 m, first step edges at (5.8, 5.0) going up
and (10.2, 5.0) going down, both northwards), nothing on frames without stairs, bad input."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from raspv_bench.scene import _apartment_frames
from raspv_perception.scene_perception import ScenePerception
from raspv_perception.scene_structure import SceneStructure
from raspv_perception.stair_model import StairDirection
from raspv_perception.stairs import StairConfig, StairDetector
from raspv_perception.stairs_msg import staircase_from_msg, staircase_to_msg
from raspv_sim.simulator import SimConfig, Simulation

# name: (avatar x, y [m], yaw [deg], head pitch [deg, down]) in the stairs world
VIEWS = {"up_near": (5.8, 3.4, 90, 25), "up_oblique": (4.5, 2.5, 70, 25), "up_far": (5.8, 1.5, 90, 25),
         "down_near": (10.2, 4.0, 90, 40), "down_close": (10.2, 4.5, 90, 50), "down_well_hidden": (10.2, 2.5, 90, 25)}
STAIR_UP = np.array([5.8, 5.0, 0.0])
STAIR_DOWN = np.array([10.2, 5.0, 0.0])


@pytest.fixture(scope="module")
def views():
    """{name: (depth m, intrinsics, world_from_camera, SceneStructure)} rendered at 640×480."""
    out = {}
    with Simulation("stairs", SimConfig(width=640, height=480)) as sim:
        for name, (x, y, yaw, pitch) in VIEWS.items():
            f = sim.render_from(x, y, math.radians(yaw), head_pitch=math.radians(pitch))
            s = ScenePerception().process(f.depth, f.intrinsics, f.world_from_camera).structure
            out[name] = (f.depth, f.intrinsics, f.world_from_camera, s)
    return out


def world(pose: np.ndarray, p: np.ndarray, direction: bool = False) -> np.ndarray:
    return pose[:3, :3] @ p if direction else pose[:3, :3] @ p + pose[:3, 3]


@pytest.mark.parametrize("name, expected, origin, min_steps", [
    ("up_near", StairDirection.ASCENDING, STAIR_UP, 6),
    ("up_oblique", StairDirection.ASCENDING, STAIR_UP, 4),
    ("up_far", StairDirection.ASCENDING, STAIR_UP, 3),
    ("down_near", StairDirection.DESCENDING, STAIR_DOWN, 6),
    ("down_close", StairDirection.DESCENDING, STAIR_DOWN, 6),
])
def test_the_staircase_is_measured(views, name, expected, origin, min_steps):
    depth, K, pose, structure = views[name]
    stair = StairDetector().detect(depth, K, structure)
    assert stair is not None, f"{name}: no staircase found"
    assert stair.direction == expected
    assert stair.riser == pytest.approx(0.17, abs=0.01)
    assert stair.tread == pytest.approx(0.29, abs=0.02)
    assert stair.width == pytest.approx(1.4, abs=0.08)
    assert len(stair.steps) >= min_steps
    T = stair.camera_from_stair
    assert np.linalg.norm(world(pose, T[:3, 3]) - origin) < 0.06            # first step's front edge, world
    walk = world(pose, T[:3, 2], direction=True)
    assert math.degrees(math.acos(np.clip(walk @ [0.0, 1.0, 0.0], -1, 1))) < 3.0    # northwards
    assert world(pose, T[:3, 1], direction=True) == pytest.approx([0, 0, -1], abs=0.03)   # S y = gravity
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    sign = 1 if expected == StairDirection.ASCENDING else -1
    heights = [s.height for s in stair.steps]
    np.testing.assert_allclose(heights, sign * 0.17 * np.arange(1, len(heights) + 1), atol=0.015)
    # horizontal distance from the camera to the first edge (1.4 m wide, running east–west)
    cam = pose[:3, 3]
    nearest_x = np.clip(cam[0], origin[0] - 0.7, origin[0] + 0.7)
    assert stair.distance == pytest.approx(math.dist(cam[:2], (nearest_x, origin[1])), abs=0.1)
    # every tread's corners lie at its height above the floor, front edge first (nearer the start)
    for step in stair.steps:
        w = np.array([world(pose, c) for c in step.tread_corners])
        assert w[:, 2] == pytest.approx(step.height, abs=0.03)
        assert (w[:2, 1].mean() - origin[1]) < (w[2:, 1].mean() - origin[1])


def test_wireframe_has_every_tread_and_riser(views):
    depth, K, pose, structure = views["up_near"]
    stair = StairDetector().detect(depth, K, structure)
    segs = stair.segments()
    assert segs.shape == (7 * len(stair.steps), 2, 3)
    assert np.isfinite(segs).all()


def test_descending_treads_hidden_behind_the_edge_are_not_guessed(views):
    # from 2.5 m before the well with the head 25° down only the bottom landing is visible
    depth, K, pose, structure = views["down_well_hidden"]
    assert StairDetector().detect(depth, K, structure) is None


def test_nothing_on_frames_without_stairs(tum_frame, nyu_frame, kinect_frames):
    detector = StairDetector()
    frames = [(d, K, None) for _, d, K in [tum_frame, nyu_frame, *kinect_frames]]
    frames += _apartment_frames(12)
    perception = ScenePerception()
    for depth, K, pose in frames:
        structure = perception.process(depth, K, pose).structure
        assert detector.detect_all(depth, K, structure) == []


def test_no_floor_no_staircase_and_bad_depth_is_ignored(views):
    depth, K, pose, structure = views["up_near"]
    assert StairDetector().detect(depth, K, SceneStructure()) is None
    noisy = depth.copy()
    noisy[::7] = np.nan
    noisy[1::11] = 0.0
    noisy[2::13] = np.inf
    stair = StairDetector().detect(noisy, K, structure)
    assert stair is not None and stair.riser == pytest.approx(0.17, abs=0.01)
    assert StairDetector().detect(np.full_like(depth, np.nan), K, structure) is None


def test_config_is_checked():
    with pytest.raises(ValueError, match="h_min .* must be below h_max"):
        StairConfig(h_min=0.3, h_max=0.2)
    with pytest.raises(ValueError, match="cell must be a positive number"):
        StairConfig(cell=0.0)
    assert dataclasses.replace(StairConfig(), min_steps=3).min_steps == 3


def test_message_round_trip(views):
    depth, K, pose, structure = views["down_near"]
    stair = StairDetector().detect(depth, K, structure)
    back = staircase_from_msg(staircase_to_msg(stair))
    assert back.direction == stair.direction and len(back.steps) == len(stair.steps)
    np.testing.assert_allclose(back.camera_from_stair, stair.camera_from_stair, atol=1e-6)
    for a, b in zip(back.steps, stair.steps):
        np.testing.assert_allclose(a.tread_corners, b.tread_corners, atol=1e-5)
        assert a.height == pytest.approx(b.height, abs=1e-6)
    assert staircase_from_msg(staircase_to_msg(None)) is None
