"""Scheduling priority for the threads a headset wearer feels (no rclpy).

On a 2-core machine the graph's processes (simulator, perception, phosphene display, headset
server) compete for the cores; a display tick or a frame send that waits for the scheduler is a
late head turn on the headset. The threads on the path from the wearer's head to the phosphenes
ask for a higher priority, as VR compositors do:

- ``realtime``: the round-robin real-time class (``SCHED_RR``, priority ``HEADSET_RT_PRIORITY``),
  with reset-on-fork so that a subprocess starts as a normal process; Linux's real-time
  throttling keeps 5 % of every second for normal processes whatever happens;
- otherwise, or when that is not allowed: a lower nice value (``HEADSET_NICE``).

The processes whose late result is carried (cameras, the simulator, perception, views) lower
themselves instead (:func:`lower_process_priority`, ``SOURCE_NICE``, ``PERCEPTION_NICE``), which needs no permission.

A headset process starts as a normal process and takes real time only once its real-time work
runs (:func:`raise_process_priority`: the bridge once built, spv once its display shows its first
frame from inputs): a replacement spv that built its node and first depth frame at real-time
priority held the bridge's frame thread up ~0.36 s after a ``kill -9`` (and drove the kernel into
real-time throttling).

Both need root or CAP_SYS_NICE (or RLIMIT_RTPRIO / RLIMIT_NICE); without them nothing changes and
the thread runs as before. Threads created afterwards inherit the class and nice value, so
background work in such a process lowers itself with :func:`lower_thread_priority`.
Measured (`raspv bench e2e`, demo graph, quiet 2-core VM) in docs/spv.md, "Priorities".
"""
from __future__ import annotations

import os
import re
import threading
from contextlib import contextmanager

HEADSET_NICE = -10           # display thread and headset server thread (without real-time permission)
# Processes whose late result is carried, not shown as a fault, yield the cores to the wearer's
# path (display, bridge, the browser page) when the machine is short: lower rates chosen on
# purpose instead of display frames dropped at random. Raising a nice value needs no permission.
SOURCE_NICE = 2              # cameras (real, recorded, simulated): behind the display and the page
PERCEPTION_NICE = 5          # scene, stairs, segmentation, odometry, planner, views: behind their camera
BACKGROUND_NICE = {"source": SOURCE_NICE, "perception": PERCEPTION_NICE}
HEADSET_RT_PRIORITY = 10     # of 1..99: the processes on the headset path (spv, bridge)
DISPLAY_RT_PRIORITY = 12     # their display and frame-sending threads, ahead of their own other work
_RESET_ON_FORK = 0x40000000  # SCHED_RESET_ON_FORK (Linux): children start as normal processes
_AUTOGROUP = "/proc/self/autogroup"
_TASKS = "/proc/self/task"
_lowered: set[int] = set()   # native ids of threads that lowered themselves on purpose (not raised with the rest)


def raise_thread_priority(nice: int = HEADSET_NICE, realtime: bool = False,
                          rt_priority: int = HEADSET_RT_PRIORITY) -> bool:
    """Give the calling thread real-time round-robin scheduling at ``rt_priority``
    (``realtime``), or the ``nice`` value, when allowed; whether it changed. (Threads of one
    real-time priority do not preempt each other: a display thread gets a higher one than the
    input callbacks of its own process.)"""
    if realtime:
        try:
            os.sched_setscheduler(0, os.SCHED_RR | _RESET_ON_FORK, os.sched_param(rt_priority))
            return True
        except (AttributeError, OSError):
            pass
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
        return True
    except (AttributeError, OSError):
        return False


def raise_process_priority(rt_priority: int = HEADSET_RT_PRIORITY, nice: int = HEADSET_NICE) -> int:
    """Give every normal thread of this process — the middleware's and the executor's, not one
    that lowered itself (:func:`lower_thread_priority`, :func:`normal_priority`) nor one already
    real-time — real-time round-robin scheduling at ``rt_priority`` (reset-on-fork), or ``nice``
    where real time is not allowed; how many threads changed. Threads started afterwards inherit
    their starter's class, as before."""
    try:
        tids = sorted(int(t) for t in os.listdir(_TASKS))
    except (OSError, ValueError):
        return 0
    changed = 0
    for tid in tids:
        if tid in _lowered:
            continue
        try:
            if os.sched_getscheduler(tid) & ~_RESET_ON_FORK != os.SCHED_OTHER:
                continue
        except (AttributeError, OSError):                # not Linux, or the thread ended
            continue
        try:
            os.sched_setscheduler(tid, os.SCHED_RR | _RESET_ON_FORK, os.sched_param(rt_priority))
            changed += 1
            continue
        except OSError:
            pass
        try:
            if os.getpriority(os.PRIO_PROCESS, tid) > nice:
                os.setpriority(os.PRIO_PROCESS, tid, nice)
                changed += 1
        except OSError:
            pass
    return changed


def lower_process_priority(nice: int) -> str:
    """Give this process ``nice`` before it starts threads (they inherit it); what was done.

    Linux with autogroup (``/proc/sys/kernel/sched_autogroup_enabled``, the default of most
    distributions) shares the CPU between *sessions* first and applies a thread's nice value only
    within its session: a process the launcher started in a session of its own (it is the
    session leader) therefore also sets its session's nice (``/proc/self/autogroup``). A process
    started from a user's shell shares that shell's session and leaves it alone."""
    done = []
    try:
        os.setpriority(os.PRIO_PROCESS, 0, max(nice, os.getpriority(os.PRIO_PROCESS, 0)))
        done.append(f"nice {nice}")
    except (AttributeError, OSError):
        pass
    try:
        if os.getsid(0) == os.getpid() and session_nice() is not None:
            with open(_AUTOGROUP, "w") as f:
                f.write(str(nice))
            if session_nice() == nice:                  # (a sandbox may accept the write and ignore it)
                done.append(f"session nice {nice}")
    except (AttributeError, OSError):
        pass
    return ", ".join(done) or "unchanged"


def session_nice() -> int | None:
    """This process's session (autogroup) nice value, or None where the kernel has no readable
    autogroup (``/proc/self/autogroup`` absent, or empty as in some sandboxes)."""
    try:
        with open(_AUTOGROUP) as f:
            m = re.search(r"nice\s+(-?\d+)", f.read())
    except OSError:
        return None
    return int(m.group(1)) if m else None


def lower_thread_priority(nice: int) -> None:
    """Make the calling thread a normal thread (leaving a real-time class it inherited) with the
    given ``nice`` value, where allowed (background builds, checks); :func:`raise_process_priority`
    leaves it so."""
    _lowered.add(threading.get_native_id())
    try:
        if os.sched_getscheduler(0) & ~_RESET_ON_FORK != os.SCHED_OTHER:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (AttributeError, OSError):
        pass
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
    except (AttributeError, OSError):
        pass


@contextmanager
def normal_priority(nice: int = 0):
    """Run a block (a long start-up build) as a normal thread, then restore the calling
    thread's class and nice value."""
    try:
        policy, param = os.sched_getscheduler(0) & ~_RESET_ON_FORK, os.sched_getparam(0)
        old_nice = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    except (AttributeError, OSError):
        yield
        return
    lower_thread_priority(nice)
    try:
        yield
    finally:
        _lowered.discard(threading.get_native_id())
        try:
            if policy != os.SCHED_OTHER:
                os.sched_setscheduler(0, policy | _RESET_ON_FORK, param)
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), old_nice)
        except OSError:
            pass
