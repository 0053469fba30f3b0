"""Device time → host time, and pacing of recordings."""
import numpy as np
import pytest

from raspv_camera.sensor_clock import PlaybackClock, SensorClock


def test_offset_is_the_smallest_transfer_delay_and_differences_stay_the_devices():
    rng = np.random.default_rng(1)
    offset = 1000.0                                   # host clock − device clock [s]
    sensor = 5.0 + np.arange(300) / 30.0
    delay = 0.004 + rng.exponential(0.006, sensor.size)    # USB transfer + scheduling, ≥ 4 ms
    delay[::50] = 0.004                                    # now and then the fastest transfer
    clock = SensorClock()
    stamps = np.array([clock.host_time(s, s + offset + d) for s, d in zip(sensor, delay)])
    late = stamps[50:] - (sensor[50:] + offset)            # after the first fastest transfer
    assert np.all(late >= 0.004 - 1e-9) and np.all(late <= 0.004 + 2e-4 * 2.0)
    # between two fastest transfers (1.7 s) the offset creeps up by at most 2e-4 s/s, and drops
    # back at the next one: differences stay the device's to within that
    assert np.allclose(np.diff(stamps[50:]), np.diff(sensor[50:]), atol=2e-4 * 1.7 + 1e-6)
    assert clock.at(sensor[-1]) == pytest.approx(stamps[-1])


def test_device_clock_reset_restarts_the_offset():
    clock = SensorClock()
    assert clock.at(1.0) is None
    clock.host_time(100.0, 1100.01)
    assert clock.host_time(100.1, 1100.11) == pytest.approx(1100.11)
    assert clock.host_time(0.5, 1100.21) == pytest.approx(1100.21)   # device restarted its counter


def test_slow_device_clock_is_followed_by_the_drift_allowance():
    clock = SensorClock(max_drift=2e-4)
    drift = 1e-4                                           # device clock 100 ppm slower
    for i in range(3000):
        s = i / 30.0
        out = clock.host_time(s, 10.0 + s * (1 + drift) + 0.005)
    assert out == pytest.approx(10.0 + s * (1 + drift) + 0.005, abs=2e-3)


def test_playback_is_due_at_the_recordings_pace_and_restarts_on_a_loop():
    clock = PlaybackClock(rate=2.0)
    assert clock.due(50.0, now=1000.0) == 1000.0
    assert clock.due(51.0, now=1000.1) == pytest.approx(1000.5)
    assert clock.at(52.0) == pytest.approx(1001.0)
    assert clock.due(50.0, now=1010.0) == 1010.0           # the recording started again
    with pytest.raises(ValueError):
        PlaybackClock(rate=0.0)
