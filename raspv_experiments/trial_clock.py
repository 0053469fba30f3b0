"""The clock a scripted subject's policy reads in a graph trial (no rclpy): 0 at the trial's
start, advanced frame by frame by the frame period summed as the simulator sums it
(``t += 1/rate``), so it is bit-identical to :func:`~raspv_experiments.quick_trial.quick_trial`'s
``sim.t`` and does not depend on the absolute simulation time the trial started at.

Why: a policy compares times (an obstacle is remembered while ``t - seen <= 4 s``, a command acts
``reaction_time_s`` after its frame). Frame stamps in the graph are the simulator's absolute time
rounded to nanoseconds; in a quick trial they are sums of 0.1 s from 0. An age of 40 frames then
came out 3.9999999999999996 s in one and 4.000000000000001 s in the other, an obstacle cell was
forgotten one frame earlier, and a graph trial and a quick trial of the same seed parted by
millimetres after ~7 s and by metres (another outcome) after 20 s.
"""
from __future__ import annotations


def frame_period(delta: float) -> float:
    """The simulator's step behind an observed stamp difference ``delta`` [s]: ``1/rate`` for an
    integer rate within 1 µs of it (stamps carry ns rounding), else ``delta`` itself."""
    if delta <= 0:
        return 0.0
    rate = round(1.0 / delta)
    return 1.0 / rate if rate > 0 and abs(1.0 / rate - delta) < 1e-6 else delta


class TrialClock:
    """Trial time [s] from the stamps of the trial's frames: ``at(stamp)`` for each frame in order."""

    def __init__(self, start: float = 0.0) -> None:
        self.start = float(start)           # sim time the trial started at [s] (its frames come after)
        self.last = self.start
        self.t = 0.0

    def at(self, stamp: float) -> float:
        """The trial time of the frame stamped ``stamp`` [s sim time]; a frame seen again (same stamp)
        keeps its time."""
        if stamp > self.last + 1e-9:
            self.t += frame_period(stamp - self.last)
            self.last = stamp
        return self.t
