"""The loop closer's backlog never holds up the node: on a long walk through new places it was
thousands of keyframes behind (each one optimising the whole pose graph), and saving waited for
all of them under the tracking lock, stopping waited for all of them at Ctrl-C."""
from __future__ import annotations

import time

from raspv_slam.config import SlamConfig
from raspv_slam.slam_system import SlamSystem
from tests.slam.conftest import K, pose, render

KEYFRAME_S = 0.2          # each waiting keyframe takes this long here
BACKLOG = 40              # 8 s of work in the queue


def _backlogged_system():
    system = SlamSystem(K, SlamConfig())
    rgb, depth = render(pose(0.0, 0.0, 0.0))
    system.process(0.0, rgb, depth)
    closer = system.loop_closer
    closer.wait_idle()
    closer.process = lambda kf_id: time.sleep(KEYFRAME_S)
    for _ in range(BACKLOG):
        closer.submit(0)
    return system, closer


def test_waiting_for_the_backlog_is_bounded_and_stopping_drops_it(tmp_path):
    system, closer = _backlogged_system()
    t0 = time.monotonic()
    assert closer.wait_idle(timeout_s=0.5) is False                 # still busy: says so
    system.save(tmp_path / "now", wait_for_loops_s=0.0)             # a save of what the map holds
    assert (tmp_path / "now" / "map.yaml").is_file()
    closer.stop()
    took = time.monotonic() - t0
    assert took < 0.5 * BACKLOG * KEYFRAME_S, f"{took:.1f} s: waited for the backlog"
    assert not closer.busy
    system.close()
