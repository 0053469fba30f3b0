"""Gravity from an accelerometer (no ROS): the up direction in the camera frame.

An accelerometer at rest measures the specific force, 9.81 m/s² pointing up (away from the
floor). While the camera moves, body accelerations add to it; :class:`GravityFilter` keeps an
exponential average of the samples whose magnitude is within ``max_deviation`` of g (a
walking head's accelerations are mostly rejected that way, the rest averaged out over
``time_constant`` seconds), and reports the unit up vector once ``min_samples`` such readings
have been seen within ``max_age`` seconds of the query. The samples must be expressed in the
frame perception works in (the `camera` node publishes them in the colour optical frame, the
frame of the registered depth).
"""
from __future__ import annotations

import math

import numpy as np

STANDARD_GRAVITY = 9.80665     # m/s²


class GravityFilter:
    """Low-pass up direction from accelerometer samples (see module docstring)."""

    def __init__(self, time_constant: float = 0.3, max_deviation: float = 1.5, max_age: float = 0.5,
                 min_samples: int = 3) -> None:
        if not time_constant > 0 or not max_deviation > 0 or not max_age > 0 or min_samples < 1:
            raise ValueError("time_constant, max_deviation and max_age must be positive, min_samples >= 1")
        self.time_constant = time_constant      # s
        self.max_deviation = max_deviation      # m/s² from standard gravity
        self.max_age = max_age                  # s
        self.min_samples = min_samples
        self.reset()

    def reset(self) -> None:
        self._mean: np.ndarray | None = None
        self._last_t = -math.inf
        self._count = 0
        self.rejected = 0

    def add(self, stamp: float, accel) -> bool:
        """Feed one sample (``stamp`` [s], ``accel`` (3,) [m/s²]); False when it was rejected
        (not finite, too far from g, or older than the last one)."""
        a = np.asarray(accel, dtype=np.float64).reshape(-1)
        if a.shape != (3,) or not np.isfinite(a).all() or not math.isfinite(stamp):
            self.rejected += 1
            return False
        if abs(float(np.linalg.norm(a)) - STANDARD_GRAVITY) > self.max_deviation:
            self.rejected += 1
            return False
        if stamp < self._last_t - self.max_age:       # time jumped back (a looped recording)
            self.reset()
        if self._mean is None or stamp - self._last_t > self.max_age:
            self._mean, self._count = a.copy(), 1
        else:
            alpha = 1.0 - math.exp(-max(0.0, stamp - self._last_t) / self.time_constant)
            self._mean += max(alpha, 1e-3) * (a - self._mean)
            self._count += 1
        self._last_t = max(self._last_t, stamp)
        return True

    def up(self, stamp: float | None = None) -> np.ndarray | None:
        """Unit up vector (3,), or None without enough recent samples (``stamp``: the time it is
        wanted at; None skips the age check)."""
        if self._mean is None or self._count < self.min_samples:
            return None
        if stamp is not None and abs(stamp - self._last_t) > self.max_age:
            return None
        n = float(np.linalg.norm(self._mean))
        return self._mean / n if n > 1e-6 else None
