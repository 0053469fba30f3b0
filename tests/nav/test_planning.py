import math

import numpy as np
import pytest

from raspv_camera.synthetic_scene import SyntheticRoom
from raspv_common.intrinsics import CameraIntrinsics
from raspv_nav.global_planner import GlobalPlanner, NoPathError, PlannerConfig, path_length
from raspv_nav.local_planner import DWAPlanner, lookahead_point, obstacle_points
from raspv_nav.occupancy import FREE, OCCUPIED, UNKNOWN, OccupancyGrid, inflate, load_map, save_map, MapFormatError

RES = 0.05


def two_rooms(door_open: bool = True) -> OccupancyGrid:
    """10 m × 6 m, outer walls, a dividing wall at x = 5 m with a 1 m door at y ∈ [2.5, 3.5]."""
    cells = np.zeros((120, 200), np.int8)
    cells[:2, :] = cells[-2:, :] = cells[:, :2] = cells[:, -2:] = OCCUPIED
    cells[:, 99:101] = OCCUPIED
    if door_open:
        cells[50:70, 99:101] = FREE
    return OccupancyGrid(cells, RES, (0.0, 0.0))


def test_map_round_trip_keeps_orientation(tmp_path):
    g = two_rooms()
    g.cells[5, 7] = UNKNOWN
    save_map(g, tmp_path / "m.yaml")
    back = load_map(tmp_path / "m.yaml")
    np.testing.assert_array_equal(back.cells, g.cells)
    assert back.resolution == RES
    # cell (row 0, col 0) is the lower-left corner of the world
    np.testing.assert_allclose(back.cell_to_world([[0, 0]]), [[0.025, 0.025]])


@pytest.mark.parametrize("text,fragment", [("image: m.pgm\nresolution: 0.05\n", "'origin' is missing"),
                                           ("image: m.pgm\nresolution: -1\norigin: [0, 0, 0]\n", "positive"),
                                           ("image: nope.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "not a readable image"),
                                           ("image: [\n", "invalid YAML")])
def test_bad_map_files(tmp_path, text, fragment):
    p = tmp_path / "m.yaml"
    p.write_text(text)
    with pytest.raises(MapFormatError, match=fragment.replace("[", r"\[")):
        load_map(p)


def test_path_goes_through_the_door_with_clearance():
    planner = GlobalPlanner(two_rooms(), PlannerConfig(robot_radius=0.3))
    path = planner.plan((2.0, 1.0), (8.0, 1.0))
    assert np.allclose(path[0], (2.0, 1.0)) and np.allclose(path[-1], (8.0, 1.0))
    # crosses x = 5 inside the door opening
    crossing = [p for a, b in zip(path, path[1:]) if (a[0] - 5) * (b[0] - 5) <= 0 for p in [a + (5 - a[0]) / (b[0] - a[0]) * (b - a)]]
    assert crossing and 2.5 + 0.3 <= crossing[0][1] <= 3.5 - 0.3
    # every point of the polyline keeps the robot radius from walls
    dense = np.concatenate([np.linspace(a, b, 50) for a, b in zip(path, path[1:])])
    rc = planner.grid.world_to_cell(dense)
    assert planner.clearance[rc[:, 0], rc[:, 1]].min() > 0.3
    straight = math.hypot(3, 2) * 2
    assert straight <= path_length(path) < straight * 1.25


def test_no_path_and_bad_endpoints_are_explained():
    planner = GlobalPlanner(two_rooms(door_open=False))
    with pytest.raises(NoPathError, match="no path"):
        planner.plan((2.0, 1.0), (8.0, 1.0))
    with pytest.raises(NoPathError, match="goal .* too close to an obstacle"):
        planner.plan((2.0, 1.0), (5.0, 1.0))
    with pytest.raises(NoPathError, match="outside the map"):
        planner.plan((-3.0, 1.0), (2.0, 2.0))


def test_dynamic_obstacle_in_the_door_forces_no_path_then_clears():
    g = two_rooms()
    planner = GlobalPlanner(g)
    blocked = np.zeros(g.shape, bool)
    blocked[50:70, 95:105] = True
    planner.set_dynamic_obstacles(blocked)
    with pytest.raises(NoPathError):
        planner.plan((2.0, 1.0), (8.0, 1.0))
    planner.set_dynamic_obstacles(None)
    assert len(planner.plan((2.0, 1.0), (8.0, 1.0))) >= 2


def test_inflate_grows_obstacles():
    g = two_rooms()
    assert (inflate(g, 0.3).cells == OCCUPIED).sum() > (g.cells == OCCUPIED).sum()


def test_dwa_goes_straight_when_free_and_swerves_around_an_obstacle():
    dwa = DWAPlanner()
    path = np.array([[0.0, 0.0], [6.0, 0.0]])
    free = dwa.command((0.0, 0.0, 0.0), (0.6, 0.0), path, np.empty((0, 2)))
    assert free.feasible and free.linear > 0.5 and abs(free.angular) < 0.2
    # the global planner, told about the obstacle, bends the path around it (to the left)
    wall = np.array([[1.2, y] for y in np.linspace(-0.3, 0.3, 13)])
    around = np.array([[0.0, 0.0], [1.2, 0.9], [2.4, 0.0], [6.0, 0.0]])
    swerve = dwa.command((0.0, 0.0, 0.0), (0.6, 0.0), around, wall)
    assert swerve.feasible
    assert np.linalg.norm(swerve.trajectory[:, None] - wall[None], axis=2).min() > dwa.config.robot_radius
    assert swerve.angular > 0.2
    boxed = np.array([[math.cos(a) * 0.25, math.sin(a) * 0.25] for a in np.linspace(0, 2 * math.pi, 72)])
    assert not dwa.command((0.0, 0.0, 0.0), (0.0, 0.0), path, boxed).feasible  # already touching: stop


def test_lookahead_point_follows_the_path():
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    np.testing.assert_allclose(lookahead_point(path, np.array([1.0, 0.1]), 1.5), [2.0, 0.5])
    np.testing.assert_allclose(lookahead_point(path, np.array([0.0, 0.0]), 10.0), [2.0, 2.0])


def test_obstacle_points_from_depth_land_on_the_boxes():
    intr = CameraIntrinsics.from_hfov(160, 120, 60.0)
    room = SyntheticRoom(intr)
    pose = room.pose_at(0.0)   # at (1.6, 0) looking along +y: the tall box at x ∈ [-0.4, 0.4], y ∈ [2.0, 2.6] is ahead-left
    _, depth = room.render(pose)
    pts = obstacle_points(depth, intr, pose, max_range=8.0, stride=2)
    assert len(pts) > 50
    on_box = (pts[:, 0] > -0.45) & (pts[:, 0] < 0.45) & (pts[:, 1] > 1.95) & (pts[:, 1] < 2.65)
    on_walls = (np.abs(np.abs(pts[:, 0]) - 4.0) < 0.05) | (np.abs(np.abs(pts[:, 1]) - 3.0) < 0.05)
    on_other_boxes = (pts[:, 0] > 2.25) & (pts[:, 1] > -0.65) & (pts[:, 1] < 0.65)
    assert (on_box | on_walls | on_other_boxes).all()
    assert on_box.sum() > 10
