"""When the spv node's next display frame is due (no ROS).

A display frame is due every ``period`` s on absolute deadlines. When the display *follows its
input* (``display_on_input``; with the temporal model off or recursive — not with the look-up
table, which steps in whole display frames), new content — a head turn, a new camera frame — makes a frame due at once instead of at
the next deadline, but never sooner than ``min_gap`` after the previous frame, so the stream
stays at most 1/min_gap frames per second. The regular deadlines then restart from that frame.
Without input the display ticks at the period, as before.

This cuts the wait for the next tick (uniform 0..period, 20 ms at 50 Hz) out of the
motion-to-phosphene latency: a 50 Hz clock alone puts one period into the p95 of `bench e2e`.
"""
from __future__ import annotations

import threading
import time

MIN_GAP_FRACTION = 0.25     # a frame follows input no sooner than this many periods after the previous one


def next_due(deadline: float, last_frame: float | None, poked_at: float | None, period: float,
             follow_input: bool, min_gap_fraction: float = MIN_GAP_FRACTION) -> float:
    """Monotonic time [s] the next frame is due: the regular ``deadline``, or, with
    ``follow_input`` and content that arrived at ``poked_at`` (None: nothing new), that arrival
    held back to ``min_gap_fraction`` × ``period`` after the previous frame (``last_frame``)."""
    if not follow_input or poked_at is None:
        return deadline
    earliest = poked_at if last_frame is None else max(poked_at, last_frame + min_gap_fraction * period)
    return min(deadline, earliest)


class DisplayClock:
    """Sleeps the display thread until the next frame is due (:func:`next_due`); other threads
    call :meth:`poke` when new content arrives and :meth:`stop` to end the loop."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._poked_at: float | None = None
        self._stopped = False
        self._deadline: float | None = None
        self._last_frame: float | None = None

    def poke(self) -> None:
        """New content to show (from any thread)."""
        with self._cond:
            if self._poked_at is None:
                self._poked_at = time.monotonic()
                self._cond.notify()

    def stop(self) -> None:
        with self._cond:
            self._stopped = True
            self._cond.notify()

    def wait(self, period: float, follow_input: bool) -> bool:
        """Block until the next frame is due; False when stopped. After a stall longer than a
        period the deadlines restart from now (the frames missed are the caller's to count)."""
        with self._cond:
            now = time.monotonic()
            if self._deadline is None:
                self._deadline = now
            else:
                self._deadline += period
                if self._deadline < now - period:
                    self._deadline = now
            while not self._stopped:
                now = time.monotonic()
                due = next_due(self._deadline, self._last_frame, self._poked_at, period, follow_input)
                if due <= now:
                    break
                self._cond.wait(due - now)
            if self._stopped:
                return False
            if follow_input and self._poked_at is not None and now < self._deadline:
                self._deadline = now               # the regular deadlines restart from this frame
            self._poked_at = None
            self._last_frame = now
            return True
