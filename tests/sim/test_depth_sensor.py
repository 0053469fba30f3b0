"""Optional depth-sensor realism: noise growing with distance, quantisation, missing pixels."""
from __future__ import annotations

import numpy as np
import pytest

from raspv_sim.depth_sensor import DepthSensorConfig, DepthSensorModel
from raspv_sim.simulator import SimConfig, Simulation


def planes(z_left: float, z_right: float, shape=(120, 160)) -> np.ndarray:
    d = np.full(shape, z_left, np.float32)
    d[:, shape[1] // 2:] = z_right
    return d


def test_noise_grows_with_distance_squared():
    model = DepthSensorModel(DepthSensorConfig(subpixel=0, edge_jump=0, dark_dropout=0), fx=277.0, seed=1)
    out = model.apply(planes(1.0, 4.0))
    s_near, s_far = np.nanstd(out[:, 10:70]), np.nanstd(out[:, 90:150])
    assert s_near == pytest.approx(0.0014, rel=0.15)
    assert s_far == pytest.approx(0.0014 * 16, rel=0.15)


def test_quantisation_snaps_to_disparity_steps():
    model = DepthSensorModel(DepthSensorConfig(noise_at_1m=0, edge_jump=0, dark_dropout=0), fx=277.0)
    z = np.linspace(2.0, 3.0, 200, dtype=np.float32).reshape(1, -1)
    out = model.apply(z)
    disparity = 277.0 * 0.075 / np.unique(out)        # px
    assert np.diff(disparity) == pytest.approx(-1 / 8, abs=1e-3)   # neighbouring levels 1/8 px apart
    assert len(disparity) == 29                        # 10.4 px at 2 m … 6.9 px at 3 m
    assert np.abs(out - z).max() < 3.0 ** 2 / (277 * 0.075 * 8)


def test_missing_pixels_at_edges_on_dark_and_specular_surfaces_and_beyond_range():
    cfg = DepthSensorConfig(noise_at_1m=0, subpixel=0, dark_dropout=1.0, specular_dropout=1.0, max_range=6.0)
    model = DepthSensorModel(cfg, fx=277.0)
    depth = planes(1.5, 3.0)
    depth[:10] = 7.0
    rgb = np.full(depth.shape + (3,), 128, np.uint8)
    rgb[100:, :20] = 5                                 # a dark patch
    specular = np.zeros(depth.shape, bool)
    specular[50:60, 100:110] = True
    out = model.apply(depth, rgb, specular)
    assert np.isnan(out[20:90, 79:81]).all()           # the 1.5 m → 3 m edge
    assert np.isnan(out[100:, :20]).all() and np.isnan(out[50:60, 100:110]).all()
    assert np.isnan(out[:10]).all()                    # beyond 6 m
    assert np.isfinite(out[20:90, 20:70]).all()


def test_off_by_default_and_applied_when_configured():
    with Simulation("apartment", SimConfig(width=80, height=60, renderer="tiny")) as sim:
        assert sim.depth_model is None
        perfect = sim.render().depth
    with Simulation("apartment", SimConfig(width=80, height=60, renderer="tiny", depth_sensor=DepthSensorConfig())) as sim:
        noisy = sim.render().depth
    both = np.isfinite(perfect) & np.isfinite(noisy)
    assert np.isnan(noisy).sum() > np.isnan(perfect).sum()
    assert 0 < np.abs(noisy[both] - perfect[both]).mean() < 0.05


def test_a_trials_noise_depends_on_the_seed_and_its_start_not_on_the_frames_before():
    """Before, the noise was one stream from the simulator's creation: a graph that had rendered
    other trials (or frames while holding) gave a trial other noise than a quick trial of it."""
    def trial_depth(frames_before: int, start=(1.0, 1.5, 0.0), seed=0):
        config = SimConfig(width=80, height=60, renderer="tiny", depth_sensor=DepthSensorConfig(), seed=seed)
        with Simulation("apartment", config) as sim:
            for _ in range(frames_before):
                sim.step(0.1)
                sim.render(labels=False)
            sim.start_trial(*start)
            sim.step(0.1)
            return sim.render(labels=False).depth

    fresh = trial_depth(0)
    np.testing.assert_array_equal(trial_depth(3), fresh)                 # NaN where NaN, the same noise
    for other in (trial_depth(0, seed=1), trial_depth(0, start=(1.0, 1.5, 0.001))):
        both = np.isfinite(other) & np.isfinite(fresh)
        assert np.abs(other[both] - fresh[both]).max() > 0                  # another seed or start: other noise
