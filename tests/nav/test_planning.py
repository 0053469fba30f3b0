"""Global planning: map files, A* against reference searches, relocation out of the inflated zone."""
import math

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from raspv_nav.astar import AStarGrid, astar_reference, blocked_border, chain_cost, grid_graph
from raspv_nav.costmap import Costmap, CostmapConfig, inflate_obstacles
from raspv_nav.global_planner import GlobalPlanner, NoPathError, path_length
from raspv_common.occupancy import FREE, OCCUPIED, UNKNOWN, MapFormatError, OccupancyGrid, inflate, load_map, save_map

RES = 0.05


def two_rooms(door_open: bool = True) -> OccupancyGrid:
    """10 m × 6 m, outer walls, a dividing wall at x = 5 m with a 1 m door at y ∈ [2.5, 3.5]."""
    cells = np.zeros((120, 200), np.int8)
    cells[:2, :] = cells[-2:, :] = cells[:, :2] = cells[:, -2:] = OCCUPIED
    cells[:, 99:101] = OCCUPIED
    if door_open:
        cells[50:70, 99:101] = FREE
    return OccupancyGrid(cells, RES, (0.0, 0.0))


def disc(shape, centre_rc, radius_cells) -> np.ndarray:
    rr, cc = np.mgrid[:shape[0], :shape[1]]
    return (rr - centre_rc[0]) ** 2 + (cc - centre_rc[1]) ** 2 <= radius_cells ** 2


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


@pytest.mark.parametrize("seed", range(6))
def test_astar_is_optimal_against_dijkstra_and_the_textbook_astar(seed):
    """The reduced-cost search returns the cost scipy's full Dijkstra finds on the live graph
    (the oracle) and the heapq A* with an octile heuristic finds; agreement to 1e-9 relative is
    summation-order rounding. It also settles fewer cells than the reachable set (early exit)."""
    rng = np.random.default_rng(seed)
    cells = np.zeros((60, 80), np.int8)
    cells[:1], cells[-1:], cells[:, :1], cells[:, -1:] = OCCUPIED, OCCUPIED, OCCUPIED, OCCUPIED
    for _ in range(6):                                     # static walls with gaps
        r, c = rng.integers(5, 55), rng.integers(5, 75)
        if rng.random() < 0.5:
            cells[r, max(1, c - 15):c + 15] = OCCUPIED
        else:
            cells[max(1, r - 12):r + 12, c] = OCCUPIED
    grid = OccupancyGrid(cells, 0.1, (0.0, 0.0))
    config = CostmapConfig(robot_radius=0.15, inflation_radius=0.6)
    costmap = Costmap(grid, config)
    static = blocked_border(costmap.static.cell_cost)
    search = AStarGrid(static, grid.resolution)
    free = np.flatnonzero(np.isfinite(static))
    start, goal = (int(v) for v in rng.choice(free, 2, replace=False))
    live_obstacles = costmap.static_obstacles.copy()
    for _ in range(3):                                     # "people" on the live layer
        live_obstacles |= disc(cells.shape, (rng.integers(5, 55), rng.integers(5, 75)), 2)
    live = blocked_border(inflate_obstacles(live_obstacles, grid.resolution, config).cell_cost)
    live[np.unravel_index([start, goal], live.shape)] = static.ravel()[[start, goal]]   # keep the ends free
    search.set_goal(goal)
    changed = np.flatnonzero(live != static)
    near = np.unique(np.clip(changed[:, None] + np.array([0, 1, -1, 80, -80, 81, 79, -81, -79]), 0, live.size - 1))
    result = search.search(live, start, goal, near)
    oracle = dijkstra(grid_graph(live, grid.resolution), indices=start)[goal]
    textbook = astar_reference(live, grid.resolution, start, goal)
    if not math.isfinite(oracle):
        assert result.chain is None and textbook.chain is None
        return
    assert result.cost == pytest.approx(oracle, rel=1e-9)
    assert textbook.cost == pytest.approx(oracle, rel=1e-9)
    assert chain_cost(result.chain, live, grid.resolution) == pytest.approx(oracle, rel=1e-9)
    assert result.chain[0] == start and result.chain[-1] == goal
    assert result.expanded < np.isfinite(dijkstra(grid_graph(live, grid.resolution), indices=start)).sum()


def test_path_goes_through_the_door_with_clearance():
    planner = GlobalPlanner(two_rooms(), CostmapConfig(robot_radius=0.3))
    result = planner.plan((2.0, 1.0), (8.0, 1.0))
    path = result.path
    assert np.allclose(path[0], (2.0, 1.0)) and np.allclose(path[-1], (8.0, 1.0))
    assert not result.start_moved and not result.goal_moved
    # crosses x = 5 inside the door opening
    crossing = [p for a, b in zip(path, path[1:]) if (a[0] - 5) * (b[0] - 5) <= 0 for p in [a + (5 - a[0]) / (b[0] - a[0]) * (b - a)]]
    assert crossing and 2.5 + 0.3 <= crossing[0][1] <= 3.5 - 0.3
    # every point of the polyline keeps the robot radius from walls
    dense = np.concatenate([np.linspace(a, b, 50) for a, b in zip(path, path[1:])])
    rc = planner.grid.world_to_cell(dense)
    assert planner.costmap.static.clearance[rc[:, 0], rc[:, 1]].min() > 0.3
    straight = math.hypot(3, 2) * 2
    assert straight <= path_length(path) < straight * 1.25


def test_no_path_and_bad_endpoints_are_explained():
    planner = GlobalPlanner(two_rooms(door_open=False))
    with pytest.raises(NoPathError, match="no path"):
        planner.plan((2.0, 1.0), (8.0, 1.0))
    with pytest.raises(NoPathError, match="outside the map"):
        planner.plan((-3.0, 1.0), (2.0, 2.0))
    enclosed = two_rooms()
    enclosed.cells[10:80, 10:80] = OCCUPIED               # a 3.5 m block around the goal
    with pytest.raises(NoPathError, match="goal .* in an obstacle of the building map"):
        GlobalPlanner(enclosed).plan((6.0, 1.0), (2.25, 2.25))


def test_a_subject_near_a_wall_gets_a_path_that_starts_at_the_subject():
    """Within the robot radius of a wall the start moves to the nearest free cell; the path
    still begins where the subject stands (the old planner answered 'start too close')."""
    planner = GlobalPlanner(two_rooms(), CostmapConfig(robot_radius=0.3))
    start = np.array([2.0, 0.25])                          # 0.15 m from the wall's face
    result = planner.plan(start, (8.0, 1.0))
    assert result.start_moved
    assert np.allclose(result.path[0], start)
    first_free = result.path[1]
    rc = planner.grid.world_to_cell([first_free])[0]
    assert planner.costmap.static.traversable[rc[0], rc[1]]
    assert np.linalg.norm(first_free - start) < 0.3       # the nearest free cell, not somewhere far
    # a goal inside the inflated zone is moved out too, the path ends next to it
    result = planner.plan((2.0, 1.0), (8.0, 0.2))
    assert result.goal_moved and np.linalg.norm(result.path[-1] - (8.0, 0.2)) < 0.3


def test_live_obstacle_in_the_door_blocks_then_clears():
    g = two_rooms()
    costmap = Costmap(g)
    planner = GlobalPlanner(costmap)
    blocked = np.zeros(g.shape, bool)
    blocked[50:70, 95:105] = True
    state = inflate_obstacles(costmap.static_obstacles | blocked, g.resolution, costmap.config, costmap.unknown)
    with pytest.raises(NoPathError, match="block every route"):
        planner.plan((2.0, 1.0), (8.0, 1.0), state)
    assert len(planner.plan((2.0, 1.0), (8.0, 1.0)).path) >= 2


def test_live_obstacles_off_the_route_reuse_the_static_path_and_on_it_bend_it():
    g = two_rooms()
    costmap = Costmap(g)
    planner = GlobalPlanner(costmap)
    static = planner.plan((2.0, 3.0), (8.0, 3.0))
    far = inflate_obstacles(costmap.static_obstacles | disc(g.shape, (20, 30), 4), g.resolution, costmap.config)
    reused = planner.plan((2.0, 3.0), (8.0, 3.0), far)
    assert reused.expanded == 0 and reused.cost == pytest.approx(static.cost)
    person = disc(g.shape, (60, 70), 5)                    # on the straight line y = 3 at x = 3.5
    around = planner.plan((2.0, 3.0), (8.0, 3.0),
                          inflate_obstacles(costmap.static_obstacles | person, g.resolution, costmap.config))
    assert around.expanded > 0 and around.cost > static.cost
    dense = np.concatenate([np.linspace(a, b, 50) for a, b in zip(around.path, around.path[1:])])
    assert np.min(np.linalg.norm(dense - (3.525, 3.025), axis=1)) > 0.25 + 0.3


def test_inflate_grows_obstacles():
    g = two_rooms()
    assert (inflate(g, 0.3).cells == OCCUPIED).sum() > (g.cells == OCCUPIED).sum()
