"""The motion-to-phosphene probe of `raspv bench e2e` (raspv_bench.motion_latency): the step schedule,
the onset / 50 %-of-change criteria, and a real client stepping its head against a headset server."""
import asyncio
import math
import threading
import time

import numpy as np
import pytest

from raspv_hmd import protocol as P
from raspv_bench.motion_latency import StepSchedule, analyse_steps, record_steps, step_send_times
from raspv_hmd.server import Callbacks, HeadsetServer, ServerConfig


def test_schedule_alternates_and_lands_at_every_phase():
    s = StepSchedule(steps=6, amplitude_deg=40.0, hold_s=1.0, jitter_s=0.1, warmup_s=2.0, seed=3)
    assert s.times[0] == 2.0 and np.all(np.diff(s.times) >= 1.0) and np.all(np.diff(s.times) < 1.1)
    assert len({round(d % 0.05, 3) for d in np.diff(s.times)}) > 2            # not locked to a 20 Hz clock
    assert [s.yaw_deg(t + 0.01) for t in s.times] == [40.0, 0.0] * 3
    assert s.yaw_deg(1.0) == 0.0 and s.at(s.times[0] + 0.01) == (0.0, 0.0, pytest.approx(math.radians(40.0)))
    assert s.end_s > s.times[-1] + 1.0


def test_step_send_times_are_the_jumps_in_yaw():
    heads = [(0.00, P.rpy_to_quaternion(0, 0, 0)), (0.02, P.rpy_to_quaternion(0, 0, 0)),
             (0.04, P.rpy_to_quaternion(0, 0, math.radians(40))), (0.06, P.rpy_to_quaternion(0, 0, math.radians(40))),
             (0.08, P.rpy_to_quaternion(0, 0, 0))]
    times, yaws = step_send_times(heads, 20.0)
    assert list(times) == [0.04, 0.08] and np.allclose(yaws, [40.0, 0.0])


def test_bench_splits_steps_by_whether_the_head_had_looked_there_before():
    """`bench e2e` reports half-way to the new view for steps back to a direction already shown
    (the spv's view memory can fill them) apart from steps to one never shown."""
    from raspv_bench.e2e import _by_direction_seen
    from raspv_bench.motion_latency import StepResult

    results = [StepResult(t, 5.0) for t in (1.0, 2.5, 4.0)]          # the 5.5 s step skipped (views alike)
    seen, new = _by_direction_seen(results, [300.0, 20.0, 25.0], [1.0, 2.5, 4.0, 5.5], [40.0, 0.0, 40.0, 0.0])
    assert seen == [20.0, 25.0] and new == [300.0]                      # 0° held in the warm-up, 40° first at 1.0 s


def patterns():
    """Two views that share most of their light, like two walls: the same dim phosphenes
    everywhere, bright ones on the left (before the turn) or on the right (after)."""
    a = np.zeros((40, 40), np.uint8)
    a[1::4, 1::4] = 80
    b = a.copy()
    a[5:35:4, 1:18:4] = 220
    b[5:35:4, 21:38:4] = 220
    return a, b


def timeline(events):
    """Frames every 20 ms from 0 to 2 s; ``events`` maps a start time to the image shown from then."""
    t = np.round(np.arange(0.0, 2.0, 0.02), 6)
    keys = sorted(events)
    frames = np.stack([events[max(k for k in keys if k <= x)] for x in t])
    return t, t.copy(), frames


def test_onset_half_of_the_change_and_half_way_to_the_new_view():
    a, b = patterns()
    turned = b.copy()
    turned[:, 30:] = 0                     # re-projected: the new view where the last frame saw it, dark beyond
    t, stamps, frames = timeline({0.0: a, 1.04: turned, 1.12: b})
    [r], skipped = analyse_steps(t, stamps, frames, np.array([1.0]))
    assert skipped == 0 and r.change == pytest.approx(np.abs(a.astype(float) - b).mean())
    assert r.onset_s == pytest.approx(0.04) and r.onset_stamp == pytest.approx(1.04)
    assert r.half_s == pytest.approx(0.04)          # most of the step's change is on the display at once
    assert r.halfway_s == pytest.approx(0.04)       # and it is mostly the new view


def test_a_frame_gone_dark_is_a_change_but_not_half_way_to_the_new_view():
    a, b = patterns()
    t, stamps, frames = timeline({0.0: a, 1.04: np.zeros_like(a), 1.12: b})
    [r], _ = analyse_steps(t, stamps, frames, np.array([1.0]))
    assert r.onset_s == pytest.approx(0.04) and r.half_s == pytest.approx(0.04)
    assert r.halfway_s == pytest.approx(0.12)


def test_a_late_frame_is_late_by_every_measure():
    a, b = patterns()
    t, stamps, frames = timeline({0.0: a, 1.10: b})
    [r], _ = analyse_steps(t, stamps, frames, np.array([1.0]))
    assert r.onset_s == r.half_s == r.halfway_s == pytest.approx(0.10)


def test_steps_between_alike_views_are_skipped():
    a, _ = patterns()
    noisy = a.copy()
    noisy[0, 0] = 10
    t, stamps, frames = timeline({0.0: a, 1.0: noisy})
    results, skipped = analyse_steps(t, stamps, frames, np.array([1.0]))
    assert results == [] and skipped == 1


def test_a_client_stepping_its_head_sees_the_server_follow():
    """The probe against a headset server whose frames follow the last head yaw it received."""
    a, b = (np.kron(p, np.ones((8, 8), np.uint8)) for p in patterns())     # 320×320 frames
    yaw = [0.0]

    def on_head(q, _t):
        yaw[0] = math.degrees(math.atan2(2 * (q[3] * q[2] + q[0] * q[1]), 1 - 2 * (q[1] ** 2 + q[2] ** 2)))

    server = HeadsetServer(ServerConfig(host="127.0.0.1", port=0, tcp_port=None), Callbacks(on_head_orientation=on_head))
    server.start()
    stop = threading.Event()

    def feed():
        while not stop.is_set():
            server.submit_frame(b if yaw[0] > 20 else a, time.time())
            stop.wait(0.02)

    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    try:
        schedule = StepSchedule(steps=3, amplitude_deg=40.0, hold_s=0.6, warmup_s=0.6)
        data = asyncio.run(record_steps(f"http://127.0.0.1:{server.port}/", schedule))
    finally:
        stop.set()
        feeder.join()
        server.stop()
    assert data["report"]["role"] == "control" and data["report"]["frames"] > 40
    assert len(data["step_times"]) == 3 and list(np.round(data["step_yaws"])) == [40.0, 0.0, 40.0]
    assert data["frames"].shape[1:] == (80, 80)                              # kept reduced 4×
    results, skipped = analyse_steps(data["receipt"], data["stamps"], data["frames"], data["step_times"])
    assert skipped == 0 and len(results) == 3
    assert all(r.onset_s is not None and r.half_s is not None and r.halfway_s is not None
               and r.onset_s <= r.half_s for r in results)


def test_bench_rows_say_what_each_step_waited_for():
    """`bench e2e`'s per-step row: when the display's levels got half-way to the new view and from
    which camera frame, when the first camera frame looking the new way was taken (and its interval
    from the one before: a late or dropped frame), when scene perception and the display had it."""
    from raspv_bench.e2e import ProbeLog
    from raspv_bench.e2e_steps import format_rows, slowest_summary, step_rows
    from raspv_bench.motion_latency import StepResult

    old, new = np.zeros(10, np.uint8), np.full(10, 8, np.uint8)
    log = ProbeLog()
    t0 = 10.0                                          # the step's head message
    log.heads += [(t0 - 0.01, 0.0), (t0 + 0.001, 40.0)]
    # camera frames at 20 Hz looking at 0°; the one at t0 + 0.04 is late (dropped at t0 + 0.0),
    # looks the new way, and the scene has it 30 ms later
    log.poses += [(t0 - 0.1, 0.0), (t0 - 0.05, 0.0), (t0 + 0.04, 40.0), (t0 + 0.09, 40.0)]
    log.scenes += [(t0 + 0.04, t0 + 0.07)]
    # display ticks (stamp, camera frame, levels, the depth frame of their scene result): old levels,
    # then the turn re-projected from the frame at t0 − 0.05 (a quarter of the way), then the new
    # camera frame with the old frame's scene result carried into it at t0 + 0.08 (as little of the
    # way), then with its own (all the way) from t0 + 0.09
    partly = np.where(np.arange(10) < 3, 8, 0).astype(np.uint8)
    for k in range(-10, 60):
        t = t0 + 0.02 * k / 2
        if t < t0 + 0.005:
            log.frames.append((t, t0 - 0.05, old, t0 - 0.05))
        elif t < t0 + 0.075:
            log.frames.append((t, t0 - 0.05, partly, t0 - 0.05))
        elif t < t0 + 0.085:
            log.frames.append((t, t0 + 0.04, partly, t0 - 0.05))
        else:
            log.frames.append((t, t0 + 0.04, new, t0 + 0.04))
    result = StepResult(t0, 8.0, onset_s=0.012, halfway_s=0.15, onset_stamp=t0 + 0.005, halfway_stamp=t0 + 0.09)
    rows = step_rows(log, [result], [t0, t0 + 0.59], [40.0, 0.0], 40.0, model_halfway=[60.0], system_onset=[9.0])
    r = rows[0]
    assert r["k"] == 0 and r["seen"] is False and r["halfway"] == pytest.approx(150.0) and r["less"] == pytest.approx(90.0)
    assert r["lv_first"] == pytest.approx(0.3) and r["lv_half"] == pytest.approx(90.0)   # the frame's own scene
    assert r["lv_src"] == pytest.approx(40.0) and r["img_src"] == pytest.approx(40.0) and r["lv_scene"] == pytest.approx(40.0)
    assert r["cam"] == pytest.approx(40.0) and r["cam_gap"] == pytest.approx(90.0)       # one 20 Hz frame missing
    assert r["scene"] == pytest.approx(70.0) and r["shown"] == pytest.approx(80.0) and r["lv_back"] is None
    assert r["lv_cam"] == pytest.approx(0.3) and r["own"] == pytest.approx(90.0)        # carried: no nearer
    lines = format_rows(rows)
    assert len(lines) == 2 and "camgap" in lines[0] and "90.0" in lines[1]
    assert "step 0 90 ms (levels from a camera frame taken after the step" in slowest_summary(rows)
