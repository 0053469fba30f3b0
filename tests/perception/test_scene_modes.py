"""Chess-Floor, Wall-Obstacles, their combination and depth without the floor (raspv_spv modes
fed by scene perception)."""
import math

import numpy as np
import pytest

from raspv_camera.synthetic_scene import SyntheticRoom, camera_rotation
from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception import scene_labels as L
from raspv_perception.scene_perception import ScenePerception
from raspv_spv import modes
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.base import quantise
from raspv_spv.modes.depth import DepthMode
from raspv_spv.simulator import PhospheneSimulator

K = CameraIntrinsics.from_hfov(640, 480, 60.0)
NL = 8
FULL, HALF = NL - 1, int(quantise(np.array([0.5]), NL)[0])


@pytest.fixture(scope="module")
def room():
    return SyntheticRoom(K)


def pose(x, y, yaw_deg, pitch_deg=30.0, z=1.6):
    T = np.eye(4)
    T[:3, :3] = camera_rotation(math.radians(yaw_deg), math.radians(pitch_deg))
    T[:3, 3] = (x, y, z)
    return T


def frame(room, T, with_pose=True):
    rgb, depth = room.render(T)
    result = ScenePerception().process(depth, K)
    return FrameInputs(color=rgb, depth=depth, camera=K, camera_pose=T if with_pose else None,
                       scene=result.structure, scene_labels=result.labels)


def simulator(mode, **settings):
    return PhospheneSimulator(spv_config("optimist", temporal=False, mode=mode, num_levels=NL,
                                         mode_settings=settings))


def expected_world_levels(sim, inputs):
    """Full/half by the world tile (room axes, 0.5 m) of each phosphene's floor point (truth)."""
    s = sim.sampling(K)
    T = inputs.camera_pose
    rays_w = s.rays @ T[:3, :3].T
    t = -T[2, 3] / rays_w[:, 2]
    P = T[:3, 3] + t[:, None] * rays_w
    parity = (np.floor(P[:, 0] / 0.5) + np.floor(P[:, 1] / 0.5)) % 2
    return np.where(parity == 0, FULL, HALF), s


def test_chess_floor_is_fixed_to_the_world_and_only_on_free_floor(room):
    sim = simulator("chess_floor")
    for T in (pose(-1.0, -1.0, 30), pose(-0.6, -0.8, 45), pose(1.5, 1.0, 250, 35)):
        inputs = frame(room, T)
        levels = sim.levels(inputs)
        expected, s = expected_world_levels(sim, inputs)
        labels = s.sample(inputs.scene_labels, fill=L.NONE)
        on_floor = labels == L.FLOOR
        assert on_floor.sum() > 100
        assert (levels[~on_floor] == 0).all()
        agree = (levels[on_floor] == expected[on_floor]).mean()
        assert agree > 0.97                   # the rest sits on tile borders
        assert set(np.unique(levels[on_floor])) == {HALF, FULL}


def test_chess_floor_tile_size_is_a_setting(room):
    inputs = frame(room, pose(-1.0, -1.0, 30))
    small = simulator("chess_floor").levels(inputs)
    large = simulator("chess_floor", chess_tile=2.0).levels(inputs)
    on = small > 0
    # bigger tiles: fewer changes of colour between neighbouring phosphenes
    assert np.count_nonzero(np.diff(large[on].astype(int))) < np.count_nonzero(np.diff(small[on].astype(int)))


def test_chess_floor_keeps_its_first_manhattan_orientation(room):
    mode = modes.mode_class("chess_floor")({"chess_tile": 0.5})
    inputs = frame(room, pose(-1.0, -1.0, 30))
    sim = simulator("chess_floor")
    mode.levels(inputs, sim.sampling(K), NL)
    first = mode.world_angle
    assert first is not None and abs(first) < math.radians(1.0)                        # the room's axes
    inputs.scene.manhattan_z = np.array([math.sin(0.3), 0.0, math.cos(0.3)])           # a different estimate later
    mode.levels(inputs, sim.sampling(K), NL)
    assert mode.world_angle == first


def test_chess_floor_without_pose_uses_the_floor_frame(room):
    sim = simulator("chess_floor")
    a = sim.levels(frame(room, pose(-1.0, -1.0, 30), with_pose=False))
    b = sim.levels(frame(room, pose(-0.3, -1.0, 30), with_pose=False))   # moved 0.7 m along the room's x...
    # ...but yawed 30°: in F the pattern is turned to the room's axes, so it is not a plain copy
    assert (a > 0).sum() > 100 and set(np.unique(a[a > 0])) == {HALF, FULL}
    c = sim.levels(frame(room, pose(-1.0, -1.0, 30), with_pose=False))
    np.testing.assert_array_equal(a, c)                                  # same view, same pattern
    assert not np.array_equal(a, b)


def test_no_floor_no_chess(room):
    inputs = frame(room, pose(3.5, 0.0, 0, 0.0))        # facing a wall 0.5 m away
    assert not inputs.scene.floor_found
    assert not simulator("chess_floor").levels(inputs).any()


def synthetic_labels():
    labels = np.zeros((480, 640), np.uint8)
    labels[:, :128] = L.WALL
    labels[:, 128:256] = L.HORIZONTAL
    labels[:, 256:384] = L.OBSTACLE
    labels[:, 384:448] = L.FLOOR_BLOCKED
    labels[:, 448:512] = L.OTHER
    labels[:, 512:] = L.FLOOR
    return labels


def test_wall_obstacles_levels_by_class():
    labels = synthetic_labels()
    sim = simulator("wall_obstacles")
    s = sim.sampling(K)
    got = sim.levels(FrameInputs(camera=K, scene_labels=labels))
    seen = s.sample(labels, fill=L.NONE)
    assert (got[seen == L.WALL] == HALF).all()
    assert (got[(seen == L.HORIZONTAL) | (seen == L.OBSTACLE)] == FULL).all()
    assert (got[np.isin(seen, [L.FLOOR, L.FLOOR_BLOCKED, L.OTHER, L.NONE])] == 0).all()
    assert {L.WALL, L.HORIZONTAL, L.FLOOR, L.OTHER} <= set(np.unique(seen))


def test_chess_with_wall_obstacles_combines_both(room):
    inputs = frame(room, pose(-1.0, -1.0, 30))
    both = simulator("chess_wall_obstacles").levels(inputs)
    chess = simulator("chess_floor").levels(inputs)
    walls = simulator("wall_obstacles").levels(inputs)
    s = simulator("chess_floor").sampling(K)
    floor = s.sample(inputs.scene_labels, fill=L.NONE) == L.FLOOR
    np.testing.assert_array_equal(both[floor], chess[floor])
    np.testing.assert_array_equal(both[~floor], walls[~floor])
    assert (both[~floor] == HALF).any() and (both[floor] == FULL).any()


def test_depth_without_floor(room):
    inputs = frame(room, pose(-1.0, -1.0, 30))
    sim = simulator("depth_no_floor", max_depth=6.0)
    got = sim.levels(inputs)
    s = sim.sampling(K)
    plain = DepthMode({"max_depth": 6.0}).levels(inputs, s, NL)
    floor = np.isin(s.sample(inputs.scene_labels, fill=L.NONE), [L.FLOOR, L.FLOOR_BLOCKED])
    assert floor.sum() > 100 and (plain[floor] > 0).any()
    assert (got[floor] == 0).all()
    np.testing.assert_array_equal(got[~floor], plain[~floor])


def test_scene_modes_are_registered_and_refuse_frames_without_scene():
    for name in ("chess_floor", "wall_obstacles", "chess_wall_obstacles", "depth_no_floor"):
        assert modes.mode_class(name).name == name
    from raspv_spv.simulator import InputError
    with pytest.raises(InputError, match="scene_labels"):
        simulator("wall_obstacles").levels(FrameInputs(camera=K))
