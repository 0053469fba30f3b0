"""Building-map alignment (raspv_slam.building_alignment): a SLAM map's floor occupancy, seen in
a frame of its own, is placed on the building map it was cut from — exactly known placements,
the ambiguity of a symmetric building, a guess that settles it, and refusals."""
from __future__ import annotations

import math

import numpy as np
import pytest

from raspv_common.occupancy import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from raspv_slam.building_alignment import (AlignmentError, AlignmentGuess, AmbiguousAlignment, BuildingAlignment,
                                           align_to_building)

RES = 0.05


def floor_plan(walls: list[tuple[float, float, float, float]], size=(16.0, 10.0)) -> OccupancyGrid:
    """A building map: free everywhere inside ``size`` [m] but for wall segments (x0, y0, x1, y1);
    the grid has a 0.5 m margin round it (origin (-0.5, -0.5))."""
    rows, cols = int((size[1] + 1.0) / RES), int((size[0] + 1.0) / RES)
    cells = np.full((rows, cols), FREE, np.int8)
    grid = OccupancyGrid(cells, RES, (-0.5, -0.5))
    for x0, y0, x1, y1 in walls:
        n = int(max(abs(x1 - x0), abs(y1 - y0)) / (RES / 2)) + 1
        pts = np.stack([np.linspace(x0, x1, n), np.linspace(y0, y1, n)], axis=1)
        rc = grid.world_to_cell(pts)
        ok = grid.inside(rc)
        cells[rc[ok, 0], rc[ok, 1]] = OCCUPIED
    return grid


def office_plan() -> OccupancyGrid:
    """An asymmetric floor: outer walls, a corridor, rooms of different sizes, a pillar."""
    walls = [(0, 0, 16, 0), (16, 0, 16, 10), (16, 10, 0, 10), (0, 10, 0, 0),
             (0, 4, 5, 4), (6, 4, 11, 4), (12, 4, 16, 4),          # corridor's south wall with doors
             (0, 6, 3, 6), (4, 6, 16, 6),                           # north wall with a door at x 3-4
             (5, 0, 5, 4), (11, 0, 11, 4), (9, 6, 9, 10),           # room walls
             (13.0, 8.0, 13.4, 8.0), (13.4, 8.0, 13.4, 8.4), (13.4, 8.4, 13.0, 8.4), (13.0, 8.4, 13.0, 8.0)]
    return floor_plan(walls)


def seen_part(building: OccupancyGrid, region: tuple[float, float, float, float], placement: tuple[float, float, float],
              noise: float = 0.0, seed: int = 0) -> OccupancyGrid:
    """What a SLAM map of ``region`` (x0, y0, x1, y1 in B) would hold, expressed in a frame M with
    B ← M = ``placement`` (x, y, yaw_deg): the building's cells in the region, moved by M ← B,
    with Gaussian position noise [m]."""
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = region
    out = []
    for value in (OCCUPIED, FREE):
        xy = building.cell_to_world(np.argwhere(building.cells == value))
        xy = xy[(xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)]
        out.append(xy + rng.normal(0.0, noise, xy.shape) if noise else xy)
    x, y, yaw = placement
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    R = np.array([[c, -s], [s, c]])
    to_m = [(p - (x, y)) @ R for p in out]                    # M ← B: Rᵀ (p − t)
    allp = np.concatenate(to_m)
    lo = np.floor(allp.min(axis=0) / RES) * RES - 0.5
    hi = allp.max(axis=0) + 0.5
    cols, rows = (np.ceil((hi - lo) / RES).astype(int) + 1)
    grid = OccupancyGrid(np.full((rows, cols), UNKNOWN, np.int8), RES, (float(lo[0]), float(lo[1])))
    for value, p in zip((FREE, OCCUPIED), to_m[::-1]):
        rc = grid.world_to_cell(p)
        grid.cells[rc[:, 0], rc[:, 1]] = value
    return grid


def error(a: BuildingAlignment, placement) -> tuple[float, float]:
    x, y, yaw = placement
    return math.hypot(a.x - x, a.y - y), abs((a.yaw_deg - yaw + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize("placement", [(3.2, -1.5, 0.0), (7.7, 4.1, 123.0), (-2.0, 12.5, 271.5)])
def test_a_part_of_the_building_is_placed_where_it_was_cut_from(placement):
    building = office_plan()
    slam = seen_part(building, (0.0, 0.0, 12.0, 10.0), placement, noise=0.02)
    a = align_to_building(slam, building)
    dist, dyaw = error(a, placement)
    assert dist < 0.05 and dyaw < 0.5, (a, placement)
    assert a.matched > 0.9 and a.score > a.runner_up_score


def test_a_symmetric_building_is_refused_as_ambiguous_and_a_guess_settles_it():
    # a plain rectangle with a door in the middle of each long wall: turned by 180° it is the same
    building = floor_plan([(0, 0, 16, 0), (16, 0, 16, 10), (16, 10, 0, 10), (0, 10, 0, 0),
                           (0, 5, 7, 5), (9, 5, 16, 5)])
    placement = (2.0, 1.0, 30.0)
    slam = seen_part(building, (0.0, 0.0, 16.0, 10.0), placement)
    with pytest.raises(AmbiguousAlignment) as info:
        align_to_building(slam, building)
    candidates = [info.value.best, info.value.runner_up]
    assert min(error(c, placement)[0] for c in candidates) < 0.1       # the truth is one of the two named
    a = align_to_building(slam, building, guess=AlignmentGuess(2.5, 0.5, 25.0, radius=1.5, yaw_range_deg=20.0))
    dist, dyaw = error(a, placement)
    assert dist < 0.05 and dyaw < 0.5


def test_a_map_of_another_building_matches_nothing():
    building = office_plan()
    elsewhere = floor_plan([(0, 0, 3, 0), (3, 0, 3, 1.0), (3, 1.0, 0, 1.0), (0, 1.0, 0, 0)], size=(3.5, 1.5))
    rng = np.random.default_rng(1)
    cells = elsewhere.cells.copy()
    cells[rng.random(cells.shape) < 0.08] = OCCUPIED            # clutter where the building has open floor
    with pytest.raises(AlignmentError):
        align_to_building(OccupancyGrid(cells, RES, (0.0, 0.0)), building)


def test_a_map_that_saw_almost_nothing_is_refused_with_the_reason():
    building = office_plan()
    tiny = OccupancyGrid(np.full((20, 20), FREE, np.int8), RES, (0.0, 0.0))
    tiny.cells[0, :5] = OCCUPIED
    with pytest.raises(AlignmentError, match="too few walls"):
        align_to_building(tiny, building)


def test_round_trip_of_the_stored_form_and_the_matrix():
    a = BuildingAlignment(1.25, -3.5, 90.0, 0.8, 0.95, 0.3)
    assert BuildingAlignment.from_dict(a.as_dict()) == a
    T = a.matrix()
    assert np.allclose(T @ [1.0, 0.0, 0.0, 1.0], [1.25, -2.5, 0.0, 1.0])
    with pytest.raises(AlignmentError):
        BuildingAlignment.from_dict({"x": "a", "y": 0})
