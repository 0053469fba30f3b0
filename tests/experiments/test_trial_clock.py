"""The clock a graph subject's policy reads (raspv_experiments/trial_clock.py) and the simulator's
trial clock for the collision debounce: bit-identical to a quick trial's sums of frame periods,
whatever absolute time the trial started at. Before, ages were differences of absolute,
nanosecond-rounded stamps, and a boundary (an obstacle remembered while its age <= 4 s, a touch
new after 0.5 s) fell on either side depending on when the trial started."""
from __future__ import annotations

from raspv_experiments.trial_clock import TrialClock, frame_period
from raspv_sim.collision_events import CollisionMonitor, Touch


def _stamps(start: float, frames: int, rate: float = 10.0) -> list[float]:
    """A lockstep graph's frame stamps: the simulator's running sum, rounded to ns by the message."""
    t, out = start, []
    for _ in range(frames):
        t += 1.0 / rate
        out.append(round(t * 1e9) / 1e9)
    return out


def _sums(frames: int, rate: float = 10.0) -> list[float]:
    t, out = 0.0, []
    for _ in range(frames):
        t += 1.0 / rate
        out.append(t)
    return out


def test_the_trial_clock_is_the_quick_trials_clock_whatever_the_start():
    for start in (0.0, 3.7, 12.345678901, 601.3):
        clock = TrialClock(round(start * 1e9) / 1e9)
        assert [clock.at(s) for s in _stamps(start, 600)] == _sums(600), start
    clock = TrialClock(5.0)
    assert clock.at(5.1) == clock.at(5.1) == 0.1                          # a frame seen twice keeps its time


def test_absolute_stamps_put_an_age_on_either_side_of_a_boundary():
    """What the trial clock removes: the same 40-frame age is <= 4 s in one loop and not in the other."""
    flips = 0
    for start in (3.7, 12.3, 33.3, 101.1):
        stamps, sums = _stamps(start, 200), _sums(200)
        flips += sum((stamps[k + 40] - stamps[k] <= 4.0) != (sums[k + 40] - sums[k] <= 4.0) for k in range(150))
    assert flips > 0


def test_frame_period_is_the_simulators_step():
    assert frame_period(0.1000000004) == 1.0 / 10 and frame_period(1 / 30 + 3e-10) == 1.0 / 30
    assert frame_period(0.123) == 0.123 and frame_period(0.0) == 0.0


def test_the_collision_debounce_runs_on_the_clock_it_is_given():
    """A touch exactly 0.5 s (5 frames) after the last is not new on the trial clock, wherever the
    trial started in absolute time."""
    touch = Touch("wall", "wall", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    counts = set()
    for start in (0.0, 3.7, 12.3, 101.1):
        monitor, sums, stamps = CollisionMonitor(0.5), _sums(6), _stamps(start, 6)
        monitor.update(stamps[0], [touch], 0.3, clock=sums[0])
        counts.add(len(monitor.update(stamps[5], [touch], 0.3, clock=sums[5])))
    assert len(counts) == 1
