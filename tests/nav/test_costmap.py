"""Costmap layers: marking and ray-cast clearing from depth, decay in data time, inflation values."""
import math

import numpy as np
import pytest

from raspv_camera.synthetic_scene import Box, SyntheticRoom, camera_rotation
from raspv_common.intrinsics import CameraIntrinsics
from raspv_nav.costmap import Costmap, CostmapConfig, inflate_obstacles
from raspv_nav.obstacle_layer import ObstacleLayer, ObstacleLayerConfig, observe_depth
from raspv_common.occupancy import OCCUPIED, UNKNOWN, OccupancyGrid

CAM = CameraIntrinsics.from_hfov(320, 240, 60.0)
ROOM = (8.0, 6.0)


def empty_grid() -> OccupancyGrid:
    """The synthetic room's floor at 5 cm, walls left to the camera."""
    return OccupancyGrid(np.zeros((120, 160), np.int8), 0.05, (-4.0, -3.0))


def view(boxes, x=-3.0, y=0.0, yaw_deg=0.0, pitch_deg=20.0):
    """Depth and pose W ← C of a camera at eye height 1.6 m in the room with ``boxes``."""
    room = SyntheticRoom(CAM, boxes=boxes)
    T = np.eye(4)
    T[:3, :3] = camera_rotation(math.radians(yaw_deg), math.radians(pitch_deg))
    T[:3, 3] = (x, y, 1.6)
    return room.render(T)[1], T


def person(x, y):
    return Box((x - 0.25, y - 0.25, 0.0), (x + 0.25, y + 0.25, 1.75), (0.7, 0.2, 0.2))


def occupied_near(layer: ObstacleLayer, xy, radius=0.3) -> bool:
    g = layer.grid
    centres = g.cell_to_world(np.argwhere(layer.occupied()))
    return bool(len(centres)) and bool((np.linalg.norm(centres - xy, axis=1) < radius).any())


def test_a_walking_person_leaves_no_trail():
    """Cells the camera sees through are cleared at once: the person's old cells vanish as soon
    as the floor behind them is seen, not when they age out."""
    layer = ObstacleLayer(empty_grid(), ObstacleLayerConfig(decay_s=10.0))
    depth, pose = view([person(0.0, 0.0)])
    layer.add_depth(depth, CAM, pose, stamp=0.0)
    assert occupied_near(layer, (-0.25, 0.0))               # its front face, 3 m ahead
    depth, pose = view([person(0.0, 1.2)])                  # half a second later, one step aside
    layer.add_depth(depth, CAM, pose, stamp=0.5)
    assert occupied_near(layer, (-0.1, 1.2))
    assert not occupied_near(layer, (-0.25, 0.0), 0.35)     # no phantom where it was
    # the room's walls beyond are marked too (in the 0.1–1.8 m band, within 4 m): not here, 7 m away
    assert not occupied_near(layer, (4.0, 0.0), 0.5)


def test_nothing_behind_a_visible_obstacle_is_cleared():
    """Rays passing under an overhang (a high cupboard, 0.9–2.2 m) reach the floor behind it;
    its far part, marked earlier from the side, stays: a bin is cleared only up to its nearest
    hit, never behind it."""
    layer = ObstacleLayer(empty_grid(), ObstacleLayerConfig(decay_s=10.0))
    cupboard = Box((-1.2, -0.4, 0.9), (-0.4, 0.4, 2.2), (0.3, 0.3, 0.3))
    depth, pose = view([cupboard], x=-0.8, y=-2.5, yaw_deg=90.0)   # its side, seen from the side
    layer.add_depth(depth, CAM, pose, 0.0)
    assert occupied_near(layer, (-0.55, -0.4), 0.1)
    depth, pose = view([cupboard], pitch_deg=5.0)                  # now from the front: x = −3 m
    obs = layer.add_depth(depth, CAM, pose, 0.5)
    assert occupied_near(layer, (-1.2, 0.0), 0.1)                  # the front face
    seen = layer.grid.cell_to_world(np.argwhere(obs.free))
    assert (np.linalg.norm(seen - (0.5, 1.5), axis=1) < 0.1).any()     # the floor beside it: seen free
    assert occupied_near(layer, (-0.55, -0.4), 0.1)                # its far side: kept


def test_no_reading_clears_nothing_and_marks_nothing():
    grid = empty_grid()
    nan = np.full((240, 320), np.nan, np.float32)
    _, pose = view([])
    obs = observe_depth(nan, CAM, pose, grid, ObstacleLayerConfig())
    assert not obs.free.any() and len(obs.hits) == 0


def test_decay_uses_the_data_stamps_and_a_jump_back_clears():
    layer = ObstacleLayer(empty_grid(), ObstacleLayerConfig(decay_s=2.0))
    depth, pose = view([person(0.0, 0.0)])
    bag_time = 1_000_000.0                                    # nothing like the wall clock
    layer.add_depth(depth, CAM, pose, bag_time)
    assert layer.occupied(bag_time + 1.9).any()
    assert not layer.occupied(bag_time + 2.1).any()
    layer.advance(bag_time + 0.5)
    assert layer.occupied().any()                             # 'now' is the newest stamp seen
    layer.advance(bag_time - 30.0)                            # the bag looped
    assert not layer.occupied().any() and not layer.observed.any()


def test_floor_seen_free_far_beyond_the_range_is_cleared_up_to_the_range():
    grid = empty_grid()
    config = ObstacleLayerConfig(max_range=2.0)
    depth, pose = view([], pitch_deg=10.0)
    obs = observe_depth(depth, CAM, pose, grid, config)
    free = grid.cell_to_world(np.argwhere(obs.free))
    d = np.linalg.norm(free - pose[:2, 3], axis=1)
    assert d.max() <= 2.0 + 0.1 and d.max() > 1.8
    assert len(obs.hits) == 0                                 # the walls are 7 m away


def test_costmap_values_follow_the_ros_convention():
    cells = np.zeros((40, 40), np.int8)
    cells[20, 20] = OCCUPIED
    cells[:, :2] = UNKNOWN
    grid = OccupancyGrid(cells, 0.05, (0.0, 0.0))
    cm = Costmap(grid, CostmapConfig(robot_radius=0.3, inflation_radius=1.0))
    v = cm.static.occupancy_values()
    assert v[20, 20] == 100 and (v[:, :2] == -1).all()
    assert v[20, 24] == 99                                    # 0.2 m away: inscribed
    assert 1 <= v[20, 28] <= 98 and v[20, 28] > v[20, 34]     # cost falls with distance
    assert v[20, 38] == 98 or v[20, 38] < v[20, 34]
    ring = inflate_obstacles(cm.static_obstacles, 0.05, cm.config)
    assert np.isinf(ring.cell_cost[20, 24]) and ring.cell_cost[20, 28] > ring.cell_cost[20, 34] >= 1.0


def test_live_layer_is_inflated_with_the_static_one():
    grid = empty_grid()
    cm = Costmap(grid, CostmapConfig(), ObstacleLayerConfig(decay_s=2.0))
    depth, pose = view([person(0.0, 0.0)])
    cm.obstacle_layer.add_depth(depth, CAM, pose, 5.0)
    state = cm.update()
    rc = grid.world_to_cell([[-0.45, 0.0]])[0]
    assert not state.traversable[rc[0], rc[1]]                # within 0.3 m of the person's face
    assert (state.occupancy_values() == 100).sum() == cm.obstacle_layer.occupied().sum()
    assert cm.update(now=5.0 + 2.5) is cm.static              # decayed: back to the static layer


def test_bad_layer_settings_are_refused():
    with pytest.raises(ValueError, match="obstacle band"):
        ObstacleLayerConfig(min_height=1.0, max_height=0.5)
    with pytest.raises(ValueError, match="robot_radius < inflation_radius"):
        CostmapConfig(robot_radius=1.0, inflation_radius=0.5)
