"""Device timestamps → host (ROS) time (no ROS).

A live camera stamps frames on its own clock. :class:`SensorClock` maps them to host time with
the offset ``host − sensor`` estimated as a running minimum over arrivals: every arrival is
late by the transfer delay, so the smallest observed difference is the best offset (the stamp
then says when the frame was exposed plus the smallest transfer delay, not when Python got it).
The minimum is allowed to creep up slowly (``max_drift``) so that a device clock running slower
than the host's is followed, and it is restarted when the difference jumps by more than
``reset_after`` (device reset, reconnection). Differences between stamps are the device's
differences, unchanged, as long as no jump or drift correction happens.

A recording is played on a :class:`PlaybackClock`: the first frame is due now and every later
one at the same distance from it as in the recording (divided by ``rate``); a jump backwards
in the recording's time (a loop) starts over from now.
"""
from __future__ import annotations

import math


class SensorClock:
    """Offset-tracking map from device time [s] to host time [s]."""

    def __init__(self, max_drift: float = 2e-4, reset_after: float = 1.0) -> None:
        self.max_drift = max_drift          # largest upward creep of the offset [s per s]
        self.reset_after = reset_after      # a jump of the offset larger than this restarts [s]
        self.offset: float | None = None    # host − sensor [s]
        self._last_sensor = -math.inf

    def reset(self) -> None:
        self.offset = None
        self._last_sensor = -math.inf

    def host_time(self, sensor_time: float, arrival_time: float) -> float:
        """Host time of a frame stamped ``sensor_time`` by the device and received at host time
        ``arrival_time`` [s]."""
        d = arrival_time - sensor_time
        if (self.offset is None or abs(d - self.offset) > self.reset_after
                or sensor_time < self._last_sensor):
            self.offset = d
        elif d < self.offset:
            self.offset = d
        else:
            dt = max(0.0, sensor_time - self._last_sensor)
            self.offset = min(d, self.offset + self.max_drift * dt)
        self._last_sensor = sensor_time
        return sensor_time + self.offset

    def at(self, sensor_time: float) -> float | None:
        """Host time of ``sensor_time`` with the current offset (None before the first frame);
        for samples between frames (IMU), without updating the offset."""
        return None if self.offset is None else sensor_time + self.offset


class PlaybackClock:
    """When each frame of a recording is due on the host clock, at ``rate`` × real time."""

    def __init__(self, rate: float = 1.0) -> None:
        if not rate > 0:
            raise ValueError(f"playback rate must be positive, got {rate}")
        self.rate = rate
        self._anchor: tuple[float, float] | None = None   # (sensor time, host time)
        self._last_sensor = -math.inf

    def reset(self) -> None:
        self._anchor = None
        self._last_sensor = -math.inf

    def due(self, sensor_time: float, now: float) -> float:
        """Host time [s] at which the frame stamped ``sensor_time`` [s] is to be published."""
        if self._anchor is None or sensor_time < self._last_sensor:
            self._anchor = (sensor_time, now)
        self._last_sensor = sensor_time
        s0, h0 = self._anchor
        return h0 + (sensor_time - s0) / self.rate

    def at(self, sensor_time: float) -> float | None:
        """Host time of ``sensor_time`` on the current anchor (None before the first frame);
        for samples between frames (IMU), without moving the anchor."""
        if self._anchor is None:
            return None
        s0, h0 = self._anchor
        return h0 + (sensor_time - s0) / self.rate
