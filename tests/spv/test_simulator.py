"""The simulator object and the offline API on real RGB-D frames."""
import numpy as np
import pytest

from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.simulator import InputError, PhospheneSimulator, render_frame


@pytest.mark.parametrize("mode", ["grey", "depth", "edges", "edges_depth"])
def test_offline_api_renders_a_real_frame_in_every_mode(tum_frame, mode):
    color, depth, cam = tum_frame
    img = render_frame(color, depth, cam, "argus_ii", mode=mode)
    assert img.shape == (480, 800) and img.dtype == np.uint8       # 800 wide, aspect 0.6
    assert img.max() > 100


def test_device_values_can_be_overridden_and_zero_means_the_device():
    cfg = spv_config("alpha_ims", num_phosphenes=500, fov_deg=0.0, grid="", dropout=0.1)
    assert (cfg.device.num_phosphenes, cfg.device.fov_deg, cfg.device.grid) == (500, 11.0, "rectangular")
    assert cfg.device.dropout == 0.1 and (cfg.width, cfg.height) == (800, 760)
    with pytest.raises(ValueError, match="unknown setting\\(s\\) phosphenes"):
        spv_config("default", phosphenes=10)


def test_grey_levels_follow_the_colour_image(tum_frame):
    color, depth, cam = tum_frame
    sim = PhospheneSimulator(spv_config("default", temporal=False))
    frame = sim.step(FrameInputs(color=color, camera=cam))
    s = sim.sampling(cam)
    grey = color[s.rows, s.cols].astype(float) @ [0.299, 0.587, 0.114]
    assert np.array_equal(frame.levels, np.ceil(grey / 255 * 7 - 1e-9).astype(np.uint8))
    assert np.allclose(frame.brightness, frame.levels / 7)
    x, y = sim.map.centres[np.argmax(frame.levels)]
    assert frame.image[int(y), int(x)] == 255


def test_temporal_model_brightens_a_steady_input_and_leaves_trails(tum_frame):
    _, _, cam = tum_frame
    sim = PhospheneSimulator(spv_config("argus_ii", mode="depth", temporal=True))
    near = np.full((480, 640), 0.5, np.float32)
    first = sim.step(FrameInputs(depth=near, camera=cam))
    assert 0 < first.brightness.max() < 0.2                           # fast, but not instantaneous
    for _ in range(12):
        steady = sim.step(FrameInputs(depth=near, camera=cam))
    expected = steady.levels / 7
    assert np.allclose(steady.brightness, expected, atol=1e-6)       # the whole history pulsed: full level
    off = sim.step(FrameInputs(depth=np.full_like(near, np.nan), camera=cam))
    assert np.all(off.levels == 0) and np.all(off.brightness > 0.5 * expected)   # a trail, fading
    for _ in range(10):
        off = sim.step(FrameInputs(depth=np.full_like(near, np.nan), camera=cam))
    assert off.brightness.max() == 0


def test_moving_bar_leaves_a_trail_behind_it(camera):
    sim = PhospheneSimulator(spv_config("argus_iii", mode="grey", temporal=True))
    s = sim.sampling(camera)
    for step in range(8):
        img = np.zeros((480, 640, 3), np.uint8)
        x0 = 200 + 15 * step
        img[:, x0:x0 + 30] = 255
        frame = sim.step(FrameInputs(color=img, camera=camera))
    lit_now = frame.levels > 0
    behind = (s.uv[:, 0] > 200) & (s.uv[:, 0] < x0 - 20) & ~lit_now
    assert behind.any() and np.all(frame.brightness[behind] > 0)
    assert frame.brightness[lit_now].max() < 1.0


def test_dropout_and_green_output(tum_frame):
    color, _, cam = tum_frame
    sim = PhospheneSimulator(spv_config("default", temporal=False, dropout=0.3, seed=2, output_format="green"))
    frame = sim.step(FrameInputs(color=np.full_like(color, 255), camera=cam))
    assert np.all(frame.brightness[sim.map.dropped] == 0) and np.all(frame.levels == 7)
    assert frame.image.shape == (800, 800, 3) and frame.image[..., [0, 2]].max() == 0


def test_bad_inputs_are_reported_clearly(tum_frame):
    color, depth, cam = tum_frame
    sim = PhospheneSimulator(spv_config("default", mode="depth", temporal=False))
    with pytest.raises(InputError, match="needs depth, not in this frame"):
        sim.step(FrameInputs(color=color, camera=cam))
    with pytest.raises(InputError, match="needs camera"):
        sim.step(FrameInputs(depth=depth))
    with pytest.raises(InputError, match="depth must be an \\(H, W\\) float array in metres, got uint16"):
        sim.step(FrameInputs(depth=np.nan_to_num(depth).astype(np.uint16), camera=cam))
    with pytest.raises(InputError, match="depth is 480x480 but the camera model is 640x480"):
        sim.step(FrameInputs(depth=depth[:, :480], camera=cam))
    half = depth[::2, ::2]                                              # another resolution: same camera
    assert sim.step(FrameInputs(depth=half, camera=cam)).levels.max() > 0


def test_a_rebuilt_simulator_continues_the_pulse_histories(tum_frame):
    color, _, cam = tum_frame
    a = PhospheneSimulator(spv_config("default", mode="grey"))
    for _ in range(5):
        a.step(FrameInputs(color=color, camera=cam))
    b = PhospheneSimulator(spv_config("default", mode="edges"))
    b.adopt_state(a)
    assert np.array_equal(a.temporal.history, b.temporal.history)
