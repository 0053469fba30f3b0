"""The soak bench's figures (raspv_bench/soak_figures.py): memory growth fitted per process, restarts
splitting the series, and display frames missing between stamps."""
from __future__ import annotations

import numpy as np
import pytest

from raspv_bench.soak_figures import RssSeries, display_gaps


def test_growth_is_fitted_in_mb_per_hour_after_the_warm_up():
    rng = np.random.default_rng(1)
    s = RssSeries("scene")
    for t in np.arange(0.0, 1800.0, 5.0):          # 30 min: a warm-up jump, then 1 MB/h and noise
        warm = 40.0 * (1 - np.exp(-t / 20.0))
        s.add(100, t, int((150.0 + warm + t / 3600.0 + rng.normal(0, 0.05)) * 1e6))
    g = s.growth(warmup_s=120.0)
    assert g.slope_mb_h == pytest.approx(1.0, abs=0.1) and g.stderr_mb_h < 0.1
    assert g.span_s == pytest.approx(1675.0) and s.restarts == 0


def test_a_restart_starts_a_new_segment_and_the_drop_in_memory_is_not_a_negative_slope():
    s = RssSeries("spv")
    for t in range(0, 600, 5):
        s.add(1, t, int((300 + t / 60) * 1e6))                    # 60 MB/h before the crash
    for t in range(600, 1200, 5):
        s.add(2, t, int((150 + (t - 600) / 60) * 1e6))            # restarted at 150 MB, same growth
    g = s.growth(warmup_s=30.0)
    assert s.restarts == 1
    assert g.slope_mb_h == pytest.approx(60.0, rel=1e-6)


def test_too_few_samples_give_no_figure():
    s = RssSeries("x")
    s.add(1, 0.0, 1_000_000)
    assert s.growth(0.0) is None


def test_display_gaps_count_the_frames_missing_between_stamps():
    period = 1 / 50
    stamps = [i * period for i in range(100)]
    assert display_gaps(stamps, 50.0) == 0
    late = stamps[:50] + [s + 3 * period for s in stamps[50:]]   # one stall of 3 periods
    assert display_gaps(late, 50.0) == 3
    rng = np.random.default_rng(0)
    jitter = [s + rng.uniform(-0.004, 0.004) for s in stamps]        # ±4 ms around a 20 ms period
    assert display_gaps(jitter, 50.0) == 0
    assert display_gaps([], 50.0) == 0


def test_growth_that_levels_off_has_a_late_slope_near_zero_and_a_leak_does_not():
    t = np.arange(0.0, 1800.0, 5.0)
    bounded, leak = RssSeries("scene"), RssSeries("leaky")
    for ti in t:
        bounded.add(1, ti, int((160.0 + 1.5 * (1 - np.exp(-ti / 300.0))) * 1e6))   # +1.5 MB, then flat
        leak.add(2, ti, int((160.0 + 5.0 * ti / 3600.0) * 1e6))                    # 5 MB/h for ever
    b, lk = bounded.growth(120.0), leak.growth(120.0)
    assert b.slope_mb_h > 1.0 and abs(b.late_slope_mb_h) < 0.5
    assert lk.slope_mb_h == pytest.approx(5.0) and lk.late_slope_mb_h == pytest.approx(5.0)
