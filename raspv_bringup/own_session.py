"""Run a command's work in a session of its own, so that it can yield to the graph (no rclpy).

Linux with autogroup (the default of most distributions) shares the CPU between *sessions*
first: a recorder started from a user's terminal shares that terminal's session and competes
with each of the graph's nodes (a session each, the launcher's doing) as one whole share, however
high its nice value. :func:`run_in_own_session` forks; the child starts a new session (which it
may then lower, :func:`raspv_common.thread_priority.lower_process_priority`: its nice and its
session's) and does the work; the parent — still the process the user started and signals —
passes SIGINT, SIGTERM and SIGHUP on, waits, and exits with the child's code. The child is
killed with the parent (``kill -9`` of the command kills the work, as before).
"""
from __future__ import annotations

import ctypes
import os
import signal
import sys
from typing import Callable

_PR_SET_PDEATHSIG = 1
FORWARDED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def run_in_own_session(work: Callable[[], int]) -> int:
    """``work()``'s exit code, run in a session of its own (Linux; elsewhere, or when this
    process leads its session already, here)."""
    if not hasattr(os, "fork") or os.getsid(0) == os.getpid():
        return work()
    sys.stdout.flush()
    sys.stderr.flush()
    parent = os.getpid()
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, FORWARDED)   # a stop request now waits, not lost
    child = os.fork()
    if child == 0:
        os.setsid()
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
        if os.getppid() != parent:                 # the parent died before prctl
            os._exit(1)
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        return work()
    previous = {s: signal.signal(s, lambda signum, _frame: _pass_on(child, signum)) for s in FORWARDED}
    signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
    try:
        while True:
            try:
                _, status = os.waitpid(child, 0)
                break
            except ChildProcessError:
                return 1
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    code = os.waitstatus_to_exitcode(status)
    return code if code >= 0 else 128 - code


def _pass_on(child: int, signum: int) -> None:
    try:
        os.kill(child, signum)
    except ProcessLookupError:
        pass
