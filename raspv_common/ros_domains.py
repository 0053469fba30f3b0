"""ROS domain ids held by lock files in ``$TMPDIR/raspv-domains`` (no rclpy): the test harness,
sweeps and other users' graphs on one machine each hold their own and never share one."""
from __future__ import annotations

import fcntl
import os
import random
import tempfile
import time
from pathlib import Path
from typing import IO

LOW, HIGH = 30, 230          # Fast DDS: domain ids up to 232 map to valid ports


def lock_free_domain(low: int = LOW, high: int = HIGH) -> tuple[int, IO]:
    """A domain id in [low, high) no other process holds, and its locked file (the lock lasts
    until the file is closed or the process ends). RuntimeError when all are taken."""
    ids = list(range(low, high))
    random.Random(os.getpid() ^ int(time.time() * 1e6)).shuffle(ids)
    lock_dir = Path(tempfile.gettempdir()) / "raspv-domains"
    lock_dir.mkdir(exist_ok=True)
    for i in ids:
        f = open(lock_dir / f"{i}.lock", "w")
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        return i, f
    raise RuntimeError(f"no free ROS domain id in [{low}, {high}) on this machine")
