"""The navigation-path overlay projects the floor path into the phosphenes and hides occluded parts."""
import numpy as np

from raspv_camera.synthetic_scene import SyntheticRoom
from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.path_overlay import PathOverlay, densify
from raspv_spv.phosphene_map import PhospheneMap
from raspv_spv.sampling import Sampling

CAM = CameraIntrinsics.from_hfov(320, 240, 60.0)


def setup(path, depth=None):
    room = SyntheticRoom(CAM, boxes=[])
    pose = room.pose_at(0.0)        # at (1.6, 0, 1.6) looking along +y, 15° down
    _, rendered = room.render(pose)
    inputs = FrameInputs(depth=rendered if depth is None else depth, camera=CAM, camera_pose=pose,
                         extras={"nav_path": np.asarray(path, float)})
    pmap = PhospheneMap.build(spv_config("optimist", width=400).map_spec())
    return inputs, Sampling.build(pmap, CAM)


def test_path_straight_ahead_lights_a_vertical_band_below_the_horizon():
    inputs, sampling = setup([[1.6, 0.0], [1.6, 5.0]])
    lit = PathOverlay().highlight(inputs, sampling)
    assert lit.sum() > 10
    x, y = sampling.centres[lit].T
    cx, cy = sampling.K_P[0, 2], sampling.K_P[1, 2]
    assert np.all(np.abs(x - cx) < 40)           # a narrow band around the vertical centre line
    assert np.all(y > cy - 5)                    # on the floor: at or below the horizon (15° down)


def test_a_path_behind_a_wall_is_not_drawn():
    free_inputs, sampling = setup([[1.6, 0.0], [1.6, 5.0]])
    wall = np.full((240, 320), 2.5, np.float32)   # something at 2.5 m in front of the camera
    blocked_inputs, _ = setup([[1.6, 0.0], [1.6, 5.0]], depth=wall)
    overlay = PathOverlay()
    free, blocked = overlay.highlight(free_inputs, sampling), overlay.highlight(blocked_inputs, sampling)
    assert 0 < blocked.sum() < free.sum()
    assert not (blocked & ~free).any()            # only a subset: the near part stays
    near_y = sampling.centres[blocked, 1].min()
    assert near_y > sampling.centres[free, 1].min()   # the far (higher in the image) part vanished


def test_path_behind_the_camera_or_empty_lights_nothing():
    inputs, sampling = setup([[1.6, -0.5], [1.6, -4.0]])
    assert not PathOverlay().highlight(inputs, sampling).any()
    inputs, sampling = setup(np.empty((0, 2)))
    assert not PathOverlay().highlight(inputs, sampling).any()


def test_overlay_apply_dims_the_rest():
    inputs, sampling = setup([[1.6, 0.0], [1.6, 5.0]])
    levels = np.full(sampling.count, 6, np.uint8)
    out = PathOverlay().apply(levels, inputs, sampling, 8)
    lit = PathOverlay().highlight(inputs, sampling)
    assert (out[lit] == 7).all() and (out[~lit] == 3).all()


def test_densify_spacing():
    pts, s = densify(np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, 1.0, 0]]), 0.1)
    assert s[-1] == 2.0 and np.allclose(pts[-1], [1, 1, 0]) and len(pts) == 21
