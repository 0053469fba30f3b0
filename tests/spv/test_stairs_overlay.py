"""The stairs overlay draws a staircase's 3-D wireframe on the phosphenes (paper §IV-B) over
any mode: the steps light up, the rest dims, hidden edges stay off, no stair changes nothing."""
import math

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.stair_model import Staircase, StairDirection, StairStep
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes import overlay_class
from raspv_spv.modes.stairs_overlay import StairsOverlay
from raspv_spv.phosphene_map import PhospheneMap
from raspv_spv.sampling import Sampling

CAM = CameraIntrinsics.from_hfov(320, 240, 60.0)
PITCH = math.radians(25.0)        # camera looks 25° down
HEIGHT = 1.5                      # camera height above the floor [m]


def ascending_stair(ahead: float = 3.0, steps: int = 4, riser: float = 0.17, tread: float = 0.29,
                    width: float = 1.4) -> Staircase:
    """A straight staircase ``ahead`` m in front of the camera, in the camera frame."""
    down = np.array([0.0, math.cos(PITCH), math.sin(PITCH)])
    forward = np.array([0.0, -math.sin(PITCH), math.cos(PITCH)])
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2] = np.cross(down, forward), down, forward
    T[:3, 3] = ahead * forward + HEIGHT * down
    out = []
    for k in range(steps):
        h, z0 = riser * (k + 1), tread * k
        s = np.array([[-width / 2, -h, z0], [width / 2, -h, z0], [width / 2, -h, z0 + tread], [-width / 2, -h, z0 + tread]])
        out.append(StairStep(k, h, tread, width, s @ T[:3, :3].T + T[:3, 3]))
    return Staircase(StairDirection.ASCENDING, T, riser, tread, width, ahead, out)


def setup(stairs, depth=None):
    pmap = PhospheneMap.build(spv_config("optimist", width=400).map_spec())
    return FrameInputs(depth=depth, camera=CAM, extras={"stairs": stairs}), Sampling.build(pmap, CAM)


def test_registered_as_an_overlay():
    assert overlay_class("stairs") is StairsOverlay


def test_the_steps_light_up_below_the_horizon_around_the_centre():
    inputs, sampling = setup([ascending_stair()])
    lit = StairsOverlay().highlight(inputs, sampling)
    assert lit.sum() > 30
    x, y = sampling.centres[lit].T
    K = sampling.K_P
    half_width_px = K[0, 0] * 0.7 / 2.5           # the stair's half width at its nearest (~2.5 m along the axis)
    assert np.all(np.abs(x - K[0, 2]) < half_width_px * 1.3)
    horizon = K[1, 2] - K[1, 1] * math.tan(PITCH)   # image row of the horizon
    assert np.all(y > horizon)                        # every step is below eye height


def test_no_staircase_changes_nothing():
    inputs, sampling = setup([])
    levels = np.random.default_rng(0).integers(0, 8, sampling.count).astype(np.uint8)
    assert not StairsOverlay().highlight(inputs, sampling).any()
    np.testing.assert_array_equal(StairsOverlay().apply(levels, inputs, sampling, 8), levels)
    # before the first detection arrives there is no "stairs" input at all: the same
    inputs = FrameInputs(camera=CAM)
    np.testing.assert_array_equal(StairsOverlay().apply(levels, inputs, sampling, 8), levels)


def test_a_staircase_behind_a_wall_is_not_drawn():
    wall = np.full((240, 320), 1.0, np.float32)       # something 1 m in front of the camera everywhere
    inputs, sampling = setup([ascending_stair()], depth=wall)
    assert not StairsOverlay().highlight(inputs, sampling).any()
    # with the true depth (nothing in front) it is drawn
    inputs, _ = setup([ascending_stair()], depth=np.full((240, 320), np.nan, np.float32))
    assert StairsOverlay().highlight(inputs, sampling).any()


def test_apply_puts_the_stair_at_full_level_and_dims_the_rest():
    inputs, sampling = setup([ascending_stair()])
    levels = np.full(sampling.count, 6, np.uint8)
    lit = StairsOverlay().highlight(inputs, sampling)
    out = StairsOverlay().apply(levels, inputs, sampling, 8)
    assert (out[lit] == 7).all() and (out[~lit] == 3).all()


def test_wider_lines_light_more_phosphenes():
    inputs, sampling = setup([ascending_stair()])
    thin = StairsOverlay({"stairs_width_deg": 1.0}).highlight(inputs, sampling)
    thick = StairsOverlay({"stairs_width_deg": 4.0}).highlight(inputs, sampling)
    assert thick.sum() > thin.sum() and not (thin & ~thick).any()


def test_a_staircase_moves_into_the_camera_frame_of_a_later_frame():
    """The spv node draws a detection of an earlier depth frame in the current frame's camera
    (C_now ← C_detection from the camera poses at both stamps)."""
    stair = ascending_stair()
    c, s = math.cos(0.2), math.sin(0.2)
    T = np.array([[c, 0.0, s, 0.1], [0.0, 1.0, 0.0, 0.0], [-s, 0.0, c, -0.3], [0.0, 0.0, 0.0, 1.0]])
    moved = stair.in_frame(T)
    seg = stair.segments().reshape(-1, 3)
    assert np.allclose(moved.segments().reshape(-1, 3), seg @ T[:3, :3].T + T[:3, 3])
    assert np.allclose(moved.camera_from_stair, T @ stair.camera_from_stair)
    assert np.allclose(stair.segments().reshape(-1, 3), seg)                  # the original is untouched
    inputs, sampling = setup([moved])
    assert not np.array_equal(StairsOverlay().highlight(inputs, sampling),
                              StairsOverlay().highlight(setup([stair])[0], sampling))
