"""Start-up timing of node processes (no rclpy): with ``RASPV_STARTUP_REPORT=1`` in the
environment, :func:`startup_mark` prints ``startup: <stage> at <t> s``, t counted from
``RASPV_SPAWN_TIME`` (the wall-clock time the launcher spawned the process). The launcher sets
the spawn time for every node; ``raspv bench restart`` turns the report on and reads it."""
from __future__ import annotations

import os
import time

SPAWN_TIME_ENV = "RASPV_SPAWN_TIME"
STARTUP_REPORT_ENV = "RASPV_STARTUP_REPORT"


def startup_mark(stage: str) -> None:
    """Print when ``stage`` ended, in seconds since the process was spawned (if reporting is on)."""
    if os.environ.get(STARTUP_REPORT_ENV) != "1":
        return
    try:
        t = time.time() - float(os.environ[SPAWN_TIME_ENV])
    except (KeyError, ValueError):
        return
    print(f"startup: {stage} at {t:.3f} s", flush=True)
