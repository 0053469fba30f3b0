"""A map's floor occupancy (made at every save, every minute in the node) costs memory by the
mapped area, not by the keyframes: a 10-minute walk through new places makes thousands of
keyframes, and decoding all their depth images at once took the save past the memory target.
Streamed, it gives the grid the batch computation gives."""
import tracemalloc

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_slam.config import SlamConfig
from raspv_slam.features import Features
from raspv_slam.floor_occupancy import floor_occupancy, occupancy_from_points, occupancy_from_views, points_of_views
from raspv_slam.keyframe import Keyframe, encode_images
from raspv_slam.slam_map import SlamMap
from raspv_slam.static_obstacles import visibility_evidence
from tests.slam.test_static_obstacles import CAMERA_Z, LEVEL, PILLAR, WALL, K, _render, _views

FULL = CameraIntrinsics(2 * K.width, 2 * K.height, 2 * K.fx, 2 * K.fy, 2 * K.cx + 0.5, 2 * K.cy + 0.5)


def test_the_streamed_grid_is_the_batch_grid():
    views = _views()
    points = points_of_views(views, K, 0.3, 6.0)
    static = np.ones(len(points), bool)
    high = (points[:, 2] >= 0.10) & (points[:, 2] <= 1.90)
    static[high] = visibility_evidence(points[high], views, K, 6.0, voxel=0.05).static
    batch = occupancy_from_points(points, 0.05, static)
    streamed = occupancy_from_views(views, K, 0.3, 6.0)
    assert streamed.origin == batch.origin
    rows, cols = min(batch.shape[0], streamed.shape[0]), min(batch.shape[1], streamed.shape[1])
    assert abs(batch.shape[0] - streamed.shape[0]) <= 1 and abs(batch.shape[1] - streamed.shape[1]) <= 1
    np.testing.assert_array_equal(streamed.cells[:rows, :cols], batch.cells[:rows, :cols])


def _map(keyframes: int, features: int = 0) -> SlamMap:
    """A floor-anchored map of ``keyframes`` keyframes looking at the wall and the pillar from
    places 2 cm apart (M = S: the map frame is the test's), with ``features`` random ORB
    features each (53 bytes a feature)."""
    slam_map = SlamMap(FULL, SlamConfig())
    rng = np.random.default_rng(0)
    for i in range(keyframes):
        empty = Features(rng.uniform(0, 100, (features, 2)).astype(np.float32),
                         rng.integers(0, 256, (features, 32), dtype=np.uint8),
                         rng.uniform(0, 3, (features, 3)).astype(np.float32), np.zeros(features, np.int8))
        T = np.eye(4)
        T[:3, :3] = LEVEL
        T[:3, 3] = (0.0, -1.0 + 0.02 * i, CAMERA_Z)
        color, depth = encode_images(None, _render(T[:3, 3], [WALL, PILLAR]))
        slam_map.add_keyframe(Keyframe(i, float(i), empty, color, depth), T)
    slam_map.anchor(np.eye(4))
    return slam_map


def _peak_bytes(slam_map: SlamMap, work=floor_occupancy) -> int:
    tracemalloc.start()
    try:
        work(slam_map)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_the_floor_occupancy_of_a_map_does_not_grow_with_its_keyframes():
    few, many = _map(60), _map(180)
    grid_few, grid_many = floor_occupancy(few), floor_occupancy(many)
    assert (grid_many.cells == 100).sum() >= (grid_few.cells == 100).sum() > 50       # the wall is mapped
    # decoded all at once, 180 keyframes' depth and points took 3.0x the memory of 60 (1.14x streamed)
    assert _peak_bytes(many) < 1.5 * _peak_bytes(few)


def test_saving_a_map_does_not_copy_its_keyframes(tmp_path):
    """The keyframes' images and features go to disk part by part (np.savez of their
    concatenation held a copy of the whole map, twice: +511 MB on a 10-minute walk's map)."""
    from raspv_slam.map_store import load_map, save_map

    few, many = _map(60, features=1000), _map(180, features=1000)
    for m in (few, many):
        m.anchored = False                      # the occupancy is measured above: the files alone here
    save_map(few, tmp_path / "warm")
    added = sum(kf.nbytes for kf in many.keyframes.values()) - sum(kf.nbytes for kf in few.keyframes.values())
    grown = _peak_bytes(many, lambda m: save_map(m, tmp_path / "many")) - \
        _peak_bytes(few, lambda m: save_map(m, tmp_path / "few"))
    assert grown < 0.1 * added, (grown, added)                  # np.savez: 1.6x the keyframes added
    back = load_map(tmp_path / "many")
    assert sorted(back.keyframes) == sorted(many.keyframes)
    for k in (0, 179):
        np.testing.assert_array_equal(back.keyframes[k].depth_png, many.keyframes[k].depth_png)
        np.testing.assert_array_equal(back.keyframes[k].features.points, many.keyframes[k].features.points)
