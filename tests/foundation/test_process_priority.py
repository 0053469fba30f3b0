"""Cameras and the simulator, then perception, yield the cores to the wearer's path
(raspv_common.thread_priority): a process the launcher starts in a session of its own lowers its
session's share, one started from a user's shell lowers only itself; never raises itself."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from raspv_common.thread_priority import BACKGROUND_NICE, PERCEPTION_NICE, SOURCE_NICE, session_nice

# a kernel whose autogroup this process can read and set (some sandboxes show an empty file)
AUTOGROUP = session_nice() is not None and os.access("/proc/self/autogroup", os.W_OK)
CHILD = ("import os; from raspv_common.thread_priority import lower_process_priority as l, session_nice; "
         "print(l({n})); print(os.getpriority(os.PRIO_PROCESS, 0)); print(session_nice())")


def _run(nice: int, new_session: bool, before: str = "") -> list[str]:
    out = subprocess.run([sys.executable, "-c", before + CHILD.format(n=nice)], capture_output=True, text=True,
                         timeout=60, start_new_session=new_session, check=True)
    return out.stdout.split("\n")


def _expected(nice: int) -> int:
    return max(nice, os.getpriority(os.PRIO_PROCESS, 0))        # (a test run that is niced itself)


def test_perception_is_behind_its_camera_and_both_behind_the_wearer():
    assert 0 < SOURCE_NICE < PERCEPTION_NICE < 19
    assert BACKGROUND_NICE == {"source": SOURCE_NICE, "perception": PERCEPTION_NICE}


def test_a_launched_node_lowers_its_session_and_itself():
    did, nice, group = _run(PERCEPTION_NICE, new_session=True)[:3]
    assert int(nice) == _expected(PERCEPTION_NICE)
    if AUTOGROUP:
        assert group == str(PERCEPTION_NICE) and "session nice" in did


@pytest.mark.skipif(not AUTOGROUP, reason="the kernel has no autogroup")
def test_a_node_run_from_a_shell_leaves_the_shells_session_alone():
    before = session_nice()
    did, nice, group = _run(SOURCE_NICE, new_session=False)[:3]
    assert int(nice) == _expected(SOURCE_NICE) and "session" not in did
    assert group == str(before) and session_nice() == before


def test_a_node_never_raises_itself_by_lowering():
    out = _run(SOURCE_NICE, new_session=False, before="import os; os.setpriority(os.PRIO_PROCESS, 0, 15); ")
    assert int(out[1]) == _expected(15)


RAISE_CHILD = """
import os, threading
from raspv_common.thread_priority import raise_process_priority, lower_thread_priority
ready, done = threading.Barrier(3), threading.Event()
def normal():
    ready.wait(); done.wait()
def lowered():
    lower_thread_priority(7); ready.wait(); done.wait()
threads = [threading.Thread(target=normal), threading.Thread(target=lowered)]
for t in threads: t.start()
ready.wait()
print(raise_process_priority(10))
for t in threads:
    print(os.sched_getscheduler(t.native_id) & 0xFF, os.getpriority(os.PRIO_PROCESS, t.native_id))
print(os.sched_getscheduler(0) & 0xFF)
done.set()
"""


def test_raising_a_process_raises_its_normal_threads_and_leaves_lowered_ones_lowered():
    out = subprocess.run([sys.executable, "-c", RAISE_CHILD], capture_output=True, text=True, timeout=60,
                         check=True).stdout.split("\n")
    normal, lowered, main = out[1].split(), out[2].split(), int(out[3])
    assert int(lowered[0]) == os.SCHED_OTHER and int(lowered[1]) == max(7, os.getpriority(os.PRIO_PROCESS, 0))
    if int(out[0]) == 0:
        pytest.skip("no permission for real-time scheduling or a lower nice value here")
    if int(normal[0]) == os.SCHED_OTHER:               # no real-time permission: a lower nice value instead
        assert int(normal[1]) < os.getpriority(os.PRIO_PROCESS, 0) and int(out[0]) == 2
    else:
        assert int(normal[0]) == os.SCHED_RR and main == os.SCHED_RR and int(out[0]) == 2
