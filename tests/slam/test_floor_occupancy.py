"""Floor occupancy of a map whose keyframes flew off (lost tracking): the grid stays the size of
the building round the points' median instead of spanning kilometres (a 1.8 GB PGM was written)."""
import numpy as np

from raspv_common.occupancy import FREE, OCCUPIED
from raspv_slam.floor_occupancy import MAX_EXTENT, occupancy_from_points


def test_points_kilometres_away_do_not_blow_the_grid_up():
    rng = np.random.default_rng(0)
    floor = np.column_stack([rng.uniform(0, 5, 20000), rng.uniform(0, 4, 20000), np.zeros(20000)])
    wall = np.column_stack([np.full(5000, 5.0), rng.uniform(0, 4, 5000), rng.uniform(0.2, 1.8, 5000)])
    room = occupancy_from_points(np.concatenate([floor, wall]))
    stray = np.array([[-1056.0, 3.0, 0.0], [2500.0, -800.0, 1.0]] * 10)
    grid = occupancy_from_points(np.concatenate([floor, wall, stray]))
    assert grid.shape == room.shape and grid.origin == room.origin
    assert (grid.cells == FREE).sum() == (room.cells == FREE).sum() > 3000
    assert (grid.cells == OCCUPIED).sum() == (room.cells == OCCUPIED).sum() > 50
    spread = np.column_stack([np.linspace(0, 2 * MAX_EXTENT, 100000), np.zeros(100000), np.zeros(100000)])
    assert max(occupancy_from_points(spread).shape) * 0.05 <= MAX_EXTENT + 0.1
