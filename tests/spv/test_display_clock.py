"""When display frames are due (raspv_spv.display_clock) and the headset thread priorities."""
import os
import threading
import time

import pytest

from raspv_common.thread_priority import lower_thread_priority, normal_priority, raise_thread_priority
from raspv_spv.display_clock import MIN_GAP_FRACTION, DisplayClock, next_due


def test_without_input_the_deadline_rules():
    assert next_due(10.0, 9.98, None, 0.02, True) == 10.0
    assert next_due(10.0, 9.98, 9.99, 0.02, False) == 10.0       # not following input (temporal model on)


def test_new_content_is_due_at_once_but_not_sooner_than_the_gap():
    period = 0.02
    # the last frame long enough ago: due when the content arrived
    assert next_due(10.0, 9.98, 9.99, period, True) == 9.99
    # a frame just went out: held back to the minimum gap after it
    assert next_due(10.0, 9.985, 9.986, period, True) == pytest.approx(9.985 + MIN_GAP_FRACTION * period)
    # never later than the regular deadline
    assert next_due(10.0, 9.999, 9.9995, 0.02, True, min_gap_fraction=0.9) == 10.0


def _ticks(clock, period, follow, out, n):
    for _ in range(n):
        if not clock.wait(period, follow):
            return
        out.append(time.monotonic())


def test_a_poke_ends_the_wait_long_before_the_period():
    clock = DisplayClock()
    times: list[float] = []
    # a 4 s period: the poked frame is held back to the minimum gap (1 s after the first frame);
    # only the poke can end the wait within the 3 s joined
    thread = threading.Thread(target=_ticks, args=(clock, 4.0, True, times, 2))
    thread.start()
    while not times:                       # the first frame is due at once
        time.sleep(0.01)
    time.sleep(0.05)
    poked = time.monotonic()
    clock.poke()
    thread.join(timeout=3.0)
    assert not thread.is_alive(), "a poke did not wake the display clock"
    assert len(times) == 2 and times[1] >= poked
    clock.stop()


def test_without_following_input_a_poke_waits_for_the_deadline_and_stop_ends_it():
    clock = DisplayClock()
    times: list[float] = []
    thread = threading.Thread(target=_ticks, args=(clock, 30.0, False, times, 2))
    thread.start()
    while not times:
        time.sleep(0.01)
    clock.poke()
    thread.join(timeout=0.5)
    assert thread.is_alive() and len(times) == 1
    clock.stop()
    thread.join(timeout=10.0)
    assert not thread.is_alive() and len(times) == 1


def test_normal_priority_block_and_lowered_threads_leave_the_realtime_class():
    seen = {}

    def run():
        raised = raise_thread_priority(realtime=True)
        seen["raised"] = raised
        seen["policy"] = os.sched_getscheduler(0) & 0xFF
        with normal_priority():
            seen["inside"] = os.sched_getscheduler(0) & 0xFF
        seen["after"] = os.sched_getscheduler(0) & 0xFF
        lower_thread_priority(5)
        seen["lowered"] = os.sched_getscheduler(0) & 0xFF

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    assert os.sched_getscheduler(0) & 0xFF == os.SCHED_OTHER       # other threads untouched
    if not seen["raised"] or seen["policy"] != os.SCHED_RR:
        pytest.skip("no permission for real-time scheduling here (needs CAP_SYS_NICE)")
    assert seen["inside"] == os.SCHED_OTHER
    assert seen["after"] == os.SCHED_RR
    assert seen["lowered"] == os.SCHED_OTHER
