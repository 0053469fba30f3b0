"""The display budget core: counts of a configuration's per-frame work, and the verdict for a
given measured cost (fixed costs here, so the verdicts do not depend on this machine's load)."""
from __future__ import annotations

import pytest

from raspv_spv.config import spv_config
from raspv_spv.display_budget import (DisplayCost, DisplayLoad, check_display_rate, load_of_config,
                                      observed_overhead_ms, sprite_pixel_count)
from raspv_spv.simulator import PhospheneSimulator

# round numbers near what this machine measures (raspv bench budget): 1 ns per sprite pixel,
# 4 ns per phosphene, 0.15 ns per image byte, 15 us fixed
COST = DisplayCost(per_sprite_pixel_ns=1.0, per_phosphene_ns=4.0, per_image_byte_ns=0.15, fixed_us=15.0)


@pytest.mark.parametrize("settings", [dict(device="default"), dict(device="argus_ii"), dict(device="optimist"),
                                      dict(device="alpha_ims", output_format="green"),
                                      dict(device="default", num_phosphenes=3000, dropout=0.3)])
def test_the_load_is_counted_from_the_configuration_as_the_renderer_builds_it(settings):
    config = spv_config(temporal=False, **settings)
    load = load_of_config(config)
    sim = PhospheneSimulator(config)
    assert load.phosphenes == sim.count
    # counted for an average sub-pixel centre and without the image border's clipping: within 5 %
    nnz = sim.renderer.matrix.nnz
    assert 0.97 * nnz <= load.sprite_pixels <= 1.05 * nnz
    channels = 3 if config.output_format == "green" else 1
    assert load.image_bytes == config.width * config.height * channels
    assert load.rate_hz == config.frame_rate


def test_sprite_pixels_grow_with_the_phosphene_area():
    small, large = sprite_pixel_count(10.0), sprite_pixel_count(40.0)
    assert small > 0 and 12 < large / small < 20          # area ratio 16, on a pixel grid


def test_a_configuration_that_fits_is_accepted_silently():
    load = DisplayLoad(phosphenes=1000, sprite_pixels=600_000, image_bytes=640_000, rate_hz=50.0)
    v = check_display_rate(load, COST)
    assert not v.refuse and not v.warn and v.message == ""
    assert v.frame_ms == pytest.approx((600_000 + 4 * 1000 + 0.15 * 640_000) * 1e-6 + 0.015)


def test_over_half_the_period_is_a_warning_and_over_the_period_a_refusal_with_the_limit():
    warn = check_display_rate(DisplayLoad(13_000, 8_000_000, 640_000, 50.0), COST)        # ~8.2 ms of 20: fine
    assert not warn.refuse and not warn.warn
    warn = check_display_rate(DisplayLoad(13_000, 12_000_000, 640_000, 50.0), COST)       # ~12.2 ms of 20
    assert warn.warn and not warn.refuse and "will drop frames when the machine is busy" in warn.message
    refuse = check_display_rate(DisplayLoad(21_000, 13_000_000, 640_000, 100.0), COST)    # ~13.2 ms of 10
    assert refuse.refuse and "cannot run at 100 Hz" in refuse.message
    assert f"at most ~{refuse.max_phosphenes} phosphenes" in refuse.message
    # the limit is where the same phosphenes, as many as fit, just take the period
    per = 13_000_000 / 21_000
    at_limit = DisplayLoad(refuse.max_phosphenes, int(refuse.max_phosphenes * per), 640_000, 100.0)
    above = DisplayLoad(int(refuse.max_phosphenes * 1.02), int(refuse.max_phosphenes * 1.02 * per), 640_000, 100.0)
    assert not check_display_rate(at_limit, COST).refuse and check_display_rate(above, COST).refuse


def test_overhead_measured_on_the_running_node_is_added():
    load = DisplayLoad(1000, 600_000, 640_000, 50.0)
    predicted = COST.frame_ms(load)
    assert observed_overhead_ms([5.0] * 10, load, COST) == 0.0                  # too few ticks yet
    assert observed_overhead_ms([predicted + 1.5] * 100, load, COST) == pytest.approx(1.5)
    assert observed_overhead_ms([predicted / 2] * 100, load, COST) == 0.0       # never negative
    v = check_display_rate(load, COST, overhead_ms=15.0)
    assert v.warn and v.frame_ms == pytest.approx(predicted + 15.0)


def test_the_measured_cost_is_positive_and_finite():
    cost = DisplayCost.measure(repeats=3)
    for value in (cost.per_sprite_pixel_ns, cost.per_phosphene_ns, cost.per_image_byte_ns, cost.fixed_us):
        assert 0.0 <= value < 1e6
    assert cost.per_sprite_pixel_ns > 0 and cost.per_image_byte_ns > 0


def test_the_recursive_temporal_model_is_priced_and_every_headset_rate_is_said():
    from raspv_spv.display_budget import HEADSET_RATES, rate_costs

    cost = DisplayCost(per_sprite_pixel_ns=1.0, per_phosphene_ns=4.0, per_image_byte_ns=0.15, fixed_us=15.0,
                       recursive_per_phosphene_ns=40.0, recursive_fixed_us=20.0)
    config = spv_config("default", temporal_update="recursive")
    load = load_of_config(config)
    assert load.recursive and not load_of_config(spv_config("default")).recursive
    lut = DisplayLoad(load.phosphenes, load.sprite_pixels, load.image_bytes, load.rate_hz)
    extra = cost.frame_ms(load) - cost.frame_ms(lut)
    assert extra == pytest.approx((40.0 * load.phosphenes + 20e3) * 1e-6)
    # 9 ms of sprite work: fits 50 Hz, warned at 72 and 90 (more than half the period), refused at 120 Hz
    heavy = DisplayLoad(load.phosphenes, 9_000_000, load.image_bytes, 50.0, recursive=True)
    costs = rate_costs(heavy, cost)
    assert set(costs["rates"]) == {f"{r:g}" for r in HEADSET_RATES}
    assert costs["verdict"] == "ok" and costs["rates"]["50"]["verdict"] == "ok"
    assert costs["rates"]["72"]["verdict"] == costs["rates"]["90"]["verdict"] == "warn"
    assert costs["rates"]["120"]["verdict"] == "refused"
    assert costs["rates"]["120"]["share"] > 1.0 and costs["rates"]["120"]["period_ms"] == pytest.approx(8.333, abs=1e-3)
