"""Marker cores against the geometry they draw: scene perception's planes, obstacles and free
floor of the analytic room (known walls, floor and boxes), a staircase, the path, the phosphenes,
and the decimated cloud. Tolerances: 2 cm for plane fits of exact depth, 1e-9 for pure transforms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from raspv_camera.synthetic_scene import SyntheticRoom
from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.scene_perception import ScenePerception
from raspv_perception.scene_structure import PlaneType
from raspv_perception.stair_model import Staircase, StairDirection, StairStep
from raspv_viz.cloud import decimated_points, pack_cloud, unpack_cloud
from raspv_viz.phosphene_markers import phosphene_marker
from raspv_viz.scene_markers import FREE_FLOOR_LIFT, path_markers, scene_markers, stair_markers
from raspv_viz.shapes import CUBE, LINE_LIST, LINE_STRIP, SPHERE_LIST, TRIANGLE_LIST, transform_points

K = CameraIntrinsics.from_hfov(320, 240, 60.0)


def triangle_area(tris: np.ndarray) -> float:
    t = tris.reshape(-1, 3, 3)
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


@pytest.fixture(scope="module")
def room_scene():
    room = SyntheticRoom(K)
    T = room.pose_at(2.0)                                   # world ← camera
    structure = ScenePerception().process(room.render(T)[1], K).structure
    assert structure.floor_found and structure.planes and structure.obstacles
    return room, T, structure


def test_planes_are_their_hulls_in_the_world(room_scene):
    room, T, s = room_scene
    shapes = scene_markers(s, T)
    fills = [m for m in shapes if m.ns.startswith("planes/") and m.kind == TRIANGLE_LIST]
    assert len(fills) == sum(len(p.hull) >= 3 for p in s.planes)
    half_x, half_y = room.size[0] / 2, room.size[1] / 2
    for m in fills:
        plane = s.planes[m.id]
        assert m.ns == f"planes/{PlaneType(plane.type).name.lower()}"
        # the fill covers exactly the hull: same vertices, same area as the plane reports
        np.testing.assert_allclose(m.points, transform_points(T, plane.hull)[_fan_index(len(plane.hull))], atol=1e-9)
        assert triangle_area(m.points) == pytest.approx(plane.area, rel=0.01)
        if plane.type == PlaneType.FLOOR:
            np.testing.assert_allclose(m.points[:, 2], 0.0, atol=0.02)           # the world's floor z = 0
        elif plane.type == PlaneType.WALL:
            near = np.minimum(np.abs(np.abs(m.points[:, 0]) - half_x), np.abs(np.abs(m.points[:, 1]) - half_y))
            assert near.max() < 0.02                                          # on the room's walls
        outline = next(o for o in shapes if o.ns == m.ns + "/outline" and o.id == m.id)
        assert outline.kind == LINE_STRIP and np.allclose(outline.points[0], outline.points[-1])


def _fan_index(k: int) -> np.ndarray:
    return np.stack([np.zeros(k - 2, int), np.arange(1, k - 1), np.arange(2, k)], axis=1).reshape(-1)


def test_obstacle_boxes_stand_on_the_floor_inside_the_room_boxes(room_scene):
    room, T, s = room_scene
    cubes = [m for m in scene_markers(s, T) if m.ns == "obstacles"]
    assert len(cubes) == len(s.obstacles) and all(m.kind == CUBE for m in cubes)
    for m in cubes:
        centre, size = m.pose[:3, 3], np.array(m.scale)
        # the cube's axes are the floor frame's: one of them is vertical in the world
        assert np.abs(m.pose[:3, :3].T @ [0, 0, 1]).max() == pytest.approx(1.0, abs=0.01)
        bottom, top = centre[2] - size[1] / 2, centre[2] + size[1] / 2      # F's y is the vertical
        box = min(room.boxes, key=lambda b: np.linalg.norm((np.array(b.lo[:2]) + b.hi[:2]) / 2 - centre[:2]))
        assert box.lo[0] - 0.05 <= centre[0] <= box.hi[0] + 0.05 and box.lo[1] - 0.05 <= centre[1] <= box.hi[1] + 0.05
        assert top == pytest.approx(box.hi[2], abs=0.05) and bottom > -0.05


def test_free_floor_outline_lies_just_above_the_floor(room_scene):
    _, T, s = room_scene
    [line] = [m for m in scene_markers(s, T) if m.ns == "free_floor"]
    assert line.kind == LINE_STRIP and len(line.points) == len(s.free_floor) + 1
    np.testing.assert_allclose(line.points[:, 2], FREE_FLOOR_LIFT, atol=0.02)


def test_camera_frame_markers_are_the_structure_itself(room_scene):
    _, _, s = room_scene
    fills = [m for m in scene_markers(s, np.eye(4)) if m.ns.startswith("planes/") and m.kind == TRIANGLE_LIST]
    assert fills
    for m in fills:                                            # every vertex on its plane, in C
        a, b, c, d = s.planes[m.id].coefficients
        np.testing.assert_allclose(m.points @ [a, b, c] + d, 0.0, atol=0.02)


def staircase() -> Staircase:
    """Three ascending steps, riser 0.17, tread 0.28, 1 m wide, the first edge 2 m ahead of a
    camera 1.6 m above the floor (S: y down, z into the stair; C: level, looking along S's z)."""
    C_T_S = np.eye(4)
    C_T_S[:3, 3] = (0.0, 1.6, 2.0)
    steps = []
    for i in range(3):
        h, z0, z1 = 0.17 * (i + 1), 0.28 * i, 0.28 * (i + 1)
        corners_s = np.array([[-0.5, -h, z0], [0.5, -h, z0], [0.5, -h, z1], [-0.5, -h, z1]])
        steps.append(StairStep(i, h, 0.28, 1.0, transform_points(C_T_S, corners_s)))
    return Staircase(StairDirection.ASCENDING, C_T_S, 0.17, 0.28, 1.0, 2.0, steps)


def test_stair_treads_and_wireframe():
    stair = staircase()
    W_T_C = np.eye(4)
    W_T_C[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]      # optical frame looking along world x
    W_T_C[:3, 3] = (1.0, 2.0, 1.6)
    treads, edges = stair_markers(stair, W_T_C)
    assert treads.kind == TRIANGLE_LIST and edges.kind == LINE_LIST
    assert triangle_area(treads.points) == pytest.approx(3 * 0.28 * 1.0, rel=1e-9)
    tops = sorted({round(z, 9) for z in treads.points[:, 2]})
    np.testing.assert_allclose(tops, [0.17, 0.34, 0.51], atol=1e-9)           # tread heights above the floor
    np.testing.assert_allclose(edges.points, transform_points(W_T_C, stair.segments().reshape(-1, 3)), atol=1e-9)
    assert min(edges.points[:, 2]) == pytest.approx(0.0, abs=1e-9)             # the first riser starts on the floor
    assert stair_markers(None, W_T_C) == []


def test_path_line_and_goal_through_the_transform():
    path = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0]])
    T = np.eye(4)
    T[:3, 3] = (0.5, -1.0, 0.0)
    line, goal = path_markers(path, T)
    np.testing.assert_allclose(line.points, path + [0.5, -1.0, 0.0])
    np.testing.assert_allclose(goal.pose[:3, 3], [1.5, 1.0, 0.0])
    assert path_markers(np.zeros((0, 3)), T) == []


def test_phosphenes_on_their_rays():
    w = h = 400
    fov = math.radians(40.0)
    f = w / (2 * math.tan(fov / 2))
    x = np.array([w / 2, w, w / 2, 0.0])
    y = np.array([h / 2, h / 2, 0.0, h])
    brightness = np.array([1.0, 0.5, 0.0, 1.0])
    dropped = np.array([False, False, False, True])
    [m] = phosphene_marker(x, y, brightness, dropped, w, h, f, diameter_px=20.0, distance=2.0, T=np.eye(4))
    assert m.kind == SPHERE_LIST and len(m.points) == 3                         # the dropped one is not drawn
    np.testing.assert_allclose(m.points[0], [0, 0, 2.0])
    assert math.degrees(math.atan2(m.points[1][0], m.points[1][2])) == pytest.approx(20.0)   # the field's edge
    assert math.degrees(math.atan2(-m.points[2][1], m.points[2][2])) == pytest.approx(20.0)
    assert m.scale[0] == pytest.approx(20.0 / f * 2.0)
    np.testing.assert_allclose(m.colors[:, 1], [1.0, 0.5, 0.0])


def test_decimated_cloud_and_packing():
    depth = np.full((K.height, K.width), 2.0, dtype=np.float32)
    depth[:10] = np.nan
    rgb = np.zeros((K.height, K.width, 3), dtype=np.uint8)
    rgb[..., 0] = 200
    T = np.eye(4)
    T[2, 3] = 1.0
    points, colors = decimated_points(depth, K, stride=8, max_depth=8.0, T=T, rgb=rgb)
    assert len(points) == (K.height // 8 - 2) * (K.width // 8)                 # rows 0 and 8 have no depth
    np.testing.assert_allclose(points[:, 2], 3.0)
    fields, step, data = pack_cloud(points, colors)
    assert [n for n, _ in fields] == ["x", "y", "z", "rgb"] and step == 16 and len(data) == 16 * len(points)
    back, back_colors = unpack_cloud(data, [n for n, _ in fields])
    np.testing.assert_array_equal(back, points)
    np.testing.assert_array_equal(back_colors, colors)
    assert decimated_points(depth, K, 8, 1.0, T)[0].shape == (0, 3)            # all beyond max_depth
