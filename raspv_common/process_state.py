"""Whether a process on this machine runs, is stopped, or is gone — from ``/proc`` (no ROS).

A node announces its pid, its start time and its pid namespace (:func:`identity`); a consumer in
the same pid namespace asks :func:`process_state` instead of trusting gaps in data or DDS leases:
a process killed is gone at once (its entry disappears or turns zombie), one stopped with SIGSTOP
is ``stopped`` at once, and one merely starved of CPU by a loaded machine is ``running`` however
late its threads are scheduled. Reading ``/proc/<pid>/stat`` costs ~20 µs.
"""
from __future__ import annotations

import os

RUNNING, STOPPED, GONE = "running", "stopped", "gone"


def _namespace() -> str:
    """This machine's boot and this process's pid namespace: pids compare only within it."""
    try:
        boot = open("/proc/sys/kernel/random/boot_id").read().strip()
        return f"{boot}/{os.stat('/proc/self/ns/pid').st_ino}"
    except OSError:
        return ""


NAMESPACE = _namespace()


def _stat(pid: int) -> tuple[str, int] | None:
    """(state letter, start time in clock ticks since boot) of ``pid``, or None when it is gone."""
    try:
        with open(f"/proc/{int(pid)}/stat", "rb") as f:
            data = f.read()
    except (OSError, ValueError):
        return None
    fields = data[data.rfind(b")") + 2:].split()     # after "pid (comm) ": state is field 3
    try:
        return fields[0].decode(), int(fields[19])   # starttime is field 22
    except (IndexError, ValueError):
        return None


def identity() -> dict:
    """What a process announces so that others on the machine can watch it: pid, start time, namespace."""
    stat = _stat(os.getpid())
    return {"pid": os.getpid(), "started": stat[1] if stat else 0, "ns": NAMESPACE}


def process_state(pid: int, started: int) -> str:
    """:data:`RUNNING`, :data:`STOPPED` (SIGSTOP, or traced) or :data:`GONE` (exited, zombie, or
    the pid now belongs to another process) for the process announced as (``pid``, ``started``)."""
    stat = _stat(pid)
    if stat is None or (started and stat[1] != started):
        return GONE
    letter = stat[0]
    if letter in ("Z", "X", "x"):
        return GONE
    if letter in ("T", "t"):
        return STOPPED
    return RUNNING
