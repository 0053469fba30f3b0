"""A sender's timestamps on our clock (no rclpy): the gaze samples of a headset keep the eye
tracker's own timing, not the network's jitter.

Each message carries the sender's clock ``t`` [s]; it arrives at our wall clock ``r``. The
difference r − t is the clock offset plus the one-way delay, which is never negative: the
smallest difference over the last :data:`WINDOW_S` (a lower envelope, as NTP's minimum-delay
filter) is the offset plus the shortest delay, so ``t + min(r − t)`` is the sample's time on our
clock, late by at most that shortest delay (≈ 0.1–1 ms on a LAN), with the sender's intervals
intact — what a velocity threshold (saccades, :mod:`raspv_spv.gaze`) needs. The window follows
drift between the two clocks. A mapped time is never later than its arrival.
"""
from __future__ import annotations

from collections import deque

WINDOW_S = 10.0        # the minimum is taken over the arrivals of the last 10 s [s]


class SenderClock:
    """Maps one sender's timestamps onto the receiver's clock (see the module docstring)."""

    def __init__(self, window_s: float = WINDOW_S) -> None:
        self.window_s = window_s
        self._diffs: deque[tuple[float, float]] = deque()     # (arrival, arrival − sent), increasing diffs

    def map(self, sent: float, arrival: float) -> float:
        """``sent`` (sender's clock) of a message that arrived at ``arrival`` (ours) → our clock [s]."""
        diff = arrival - sent
        q = self._diffs
        while q and q[-1][1] >= diff:              # a monotonic queue: its head is the window's minimum
            q.pop()
        q.append((arrival, diff))
        while q[0][0] < arrival - self.window_s:
            q.popleft()
        return min(sent + q[0][1], arrival)
