"""Representation modes and overlays: the level rules and the plug-in interface."""
import math

import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv import modes
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.base import Mode, Overlay, quantise
from raspv_spv.phosphene_map import MapSpec, PhospheneMap
from raspv_spv.sampling import Sampling
from raspv_spv.simulator import InputError, PhospheneSimulator

from .conftest import uniform_rgb


@pytest.fixture(scope="module")
def sampling():
    cam = CameraIntrinsics.from_hfov(640, 480, 60.0)
    return Sampling.build(PhospheneMap.build(MapSpec(400, 400, 300, "hexagonal", fov_deg=30.0)), cam)


def levels_of(name, inputs, sampling, num_levels=8, **settings):
    return modes.mode_class(name)(settings).levels(inputs, sampling, num_levels)


@pytest.mark.parametrize("g", [0, 1, 36, 37, 128, 254, 255])
def test_grey_level_is_ceil_of_g_over_255(sampling, g):
    cam = sampling.camera
    lv = levels_of("grey", FrameInputs(color=uniform_rgb(g, cam), camera=cam), sampling)
    assert np.all(lv == math.ceil(g / 255 * 7))


@pytest.mark.parametrize("d, level", [(0.3, math.ceil(2.7 / 3 * 7)), (1.5, 4), (2.99, 1), (3.0, 0), (5.0, 0),
                                      (np.nan, 0), (np.inf, 0), (0.0, 0), (-1.0, 0)])
def test_depth_level_is_ceil_of_closeness_and_invalid_depth_is_off(sampling, d, level):
    cam = sampling.camera
    depth = np.full((cam.height, cam.width), d, np.float32)
    assert np.all(levels_of("depth", FrameInputs(depth=depth, camera=cam), sampling) == level)


def test_max_depth_setting_changes_the_scale(sampling):
    cam = sampling.camera
    depth = np.full((cam.height, cam.width), 3.5, np.float32)
    assert np.all(levels_of("depth", FrameInputs(depth=depth, camera=cam), sampling, max_depth=7.0) == 4)


def test_quantise_keeps_exact_multiples():
    assert list(quantise(np.array([0.0, 1 / 7, 2 / 7, 0.5, 1.0, 1.5, np.nan]), 8)) == [0, 1, 2, 4, 7, 7, 0]


def test_edges_light_the_phosphenes_along_a_step(sampling):
    cam = sampling.camera
    img = uniform_rgb(30, cam)
    img[:, 330:] = 220                                               # vertical edge at u = 329.5
    lv = levels_of("edges", FrameInputs(color=img, camera=cam), sampling)
    near = np.abs(sampling.uv[:, 0] - 329.5) <= sampling.spacing_camera_px / 2 - 1
    far = np.abs(sampling.uv[:, 0] - 329.5) > sampling.spacing_camera_px / 2 + 2
    assert np.all(lv[near] == 7) and np.all(lv[far] == 0) and near.any()


def test_depth_edges_ignore_sensor_holes(sampling):
    cam = sampling.camera
    depth = np.full((cam.height, cam.width), 2.0, np.float32)
    depth[:, 330:] = 1.0                                             # a depth step ...
    depth[100:140, 100:200] = np.nan                                 # ... and a hole in the wall
    lv = levels_of("edges_depth", FrameInputs(depth=depth, camera=cam), sampling)
    step = np.abs(sampling.uv[:, 0] - 329.5) <= sampling.spacing_camera_px / 2 - 1
    hole = (np.abs(sampling.uv[:, 0] - 150) < 40) & (np.abs(sampling.uv[:, 1] - 120) < 15)
    assert np.all(lv[step] == 7) and hole.any() and np.all(lv[hole] == 0)


class NearOverlay(Overlay):
    """Test overlay: highlights phosphenes whose depth is below 1 m."""

    name = "near"
    needs = frozenset({"depth", "camera"})

    def highlight(self, inputs, sampling):
        d = sampling.sample(inputs.depth, fill=np.nan)
        return np.isfinite(d) & (d < 1.0)


def test_overlays_highlight_to_full_and_dim_the_rest(sampling):
    ov = NearOverlay()
    levels = np.array([0, 1, 2, 3, 7] * (sampling.count // 5) + [5] * (sampling.count % 5), np.uint8)
    cam = sampling.camera
    far = FrameInputs(depth=np.full((cam.height, cam.width), 2.0, np.float32), camera=cam)
    assert np.array_equal(ov.apply(levels, far, sampling, 8), levels)          # nothing highlighted
    depth = np.full((cam.height, cam.width), 2.0, np.float32)
    depth[:, :320] = 0.5
    out = ov.apply(levels, FrameInputs(depth=depth, camera=cam), sampling, 8)
    lit = sampling.uv[:, 0] < 319
    rest = sampling.uv[:, 0] > 320.5
    assert np.all(out[lit] == 7)
    assert np.array_equal(out[rest], (levels[rest] + 1) // 2)


class CountingMode(Mode):
    """Test mode: the phosphene index modulo N_L, reading a custom input."""

    name = "counting"
    needs = frozenset({"ticks"})
    defaults = {"offset": 0}

    def levels(self, inputs, sampling, num_levels):
        n = inputs.extras["ticks"]
        return (np.arange(n) + self.settings["offset"]) % num_levels


def test_a_new_mode_or_overlay_is_a_class_plus_a_registry_line(monkeypatch, tum_frame):
    monkeypatch.setitem(modes.MODES, "counting", f"{__name__}:CountingMode")
    monkeypatch.setitem(modes.OVERLAYS, "near", f"{__name__}:NearOverlay")
    sim = PhospheneSimulator(spv_config("argus_ii", mode="counting", overlays=["near"], temporal=False,
                                        mode_settings={"offset": 3}))
    assert sim.needs == {"ticks", "depth", "camera"}
    color, depth, cam = tum_frame
    with pytest.raises(InputError, match="needs ticks, not in this frame"):
        sim.step(FrameInputs(depth=depth, camera=cam))
    frame = sim.step(FrameInputs(depth=np.full_like(depth, 2.0), camera=cam, extras={"ticks": sim.count}))
    assert np.array_equal(frame.levels, (np.arange(sim.count) + 3) % 8)        # nothing near: the mode's levels
    near = np.full_like(depth, 2.0)
    near[:, :320] = 0.5
    frame = sim.step(FrameInputs(depth=near, camera=cam, extras={"ticks": sim.count}))
    lit = sim.sampling(cam).uv[:, 0] < 319
    assert np.all(frame.levels[lit] == 7) and lit.any() and not lit.all()
    assert np.array_equal(frame.levels[~lit], (((np.arange(sim.count) + 3) % 8 + 1) // 2)[~lit])


def test_unknown_modes_are_named():
    known = ", ".join(sorted(modes.MODES))
    assert known.startswith("chess_floor, chess_wall_obstacles, depth, depth_no_floor, edges")
    with pytest.raises(KeyError) as exc:
        modes.mode_class("sonar")
    assert exc.value.args[0] == f"unknown mode 'sonar'; known: {known}"
