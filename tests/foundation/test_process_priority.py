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
