"""The simulator and perception yield the cores to the wearer's path (raspv_common.thread_priority):
a process the launcher starts in a session of its own lowers its session's share, one started from
a user's shell lowers only itself."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from raspv_common.thread_priority import BACKGROUND_NICE, PERCEPTION_NICE, SIMULATOR_NICE

AUTOGROUP = os.path.exists("/proc/self/autogroup")
CHILD = ("import os; from raspv_common.thread_priority import lower_process_priority as l; "
         "print(l({n})); print(os.getpriority(os.PRIO_PROCESS, 0)); "
         "print(open('/proc/self/autogroup').read().split()[-1] if os.path.exists('/proc/self/autogroup') else '-')")


def _run(nice: int, new_session: bool) -> list[str]:
    out = subprocess.run([sys.executable, "-c", CHILD.format(n=nice)], capture_output=True, text=True,
                         timeout=60, start_new_session=new_session, check=True)
    return out.stdout.split("\n")


def test_the_simulator_sits_between_the_display_and_perception():
    assert 0 < SIMULATOR_NICE < PERCEPTION_NICE
    assert BACKGROUND_NICE == {"simulator": SIMULATOR_NICE, "perception": PERCEPTION_NICE}


def test_a_launched_node_lowers_its_session_and_itself():
    did, nice, group = _run(PERCEPTION_NICE, new_session=True)[:3]
    assert int(nice) == max(PERCEPTION_NICE, os.getpriority(os.PRIO_PROCESS, 0))     # (a niced test run)
    if AUTOGROUP:
        assert group == str(PERCEPTION_NICE) and "session nice" in did


@pytest.mark.skipif(not AUTOGROUP, reason="the kernel has no autogroup")
def test_a_node_run_from_a_shell_leaves_the_shells_session_alone():
    before = open("/proc/self/autogroup").read().split()[-1]
    did, nice, group = _run(SIMULATOR_NICE, new_session=False)[:3]
    assert int(nice) == max(SIMULATOR_NICE, os.getpriority(os.PRIO_PROCESS, 0)) and "session" not in did
    assert group == before == open("/proc/self/autogroup").read().split()[-1]


def test_a_node_never_raises_itself_by_lowering():
    out = subprocess.run([sys.executable, "-c", "import os; os.setpriority(os.PRIO_PROCESS, 0, 15); "
                          + CHILD.format(n=SIMULATOR_NICE).split("; ", 1)[1]],
                         capture_output=True, text=True, timeout=60, check=True).stdout.split("\n")
    assert int(out[1]) == max(15, os.getpriority(os.PRIO_PROCESS, 0))
