"""A private ROS domain for each graph a sweep runs (no rclpy): a lock file per domain id in
``$TMPDIR/raspv-domains`` — the same files the test harness uses
(:func:`raspv_bringup.testing.claim_private_domain`), so sweeps, tests and other users'
graphs on one machine never share a domain. Released when the context ends.
"""
from __future__ import annotations

import contextlib
import fcntl
import os
import random
import tempfile
import time
from pathlib import Path
from typing import Iterator

LOW, HIGH = 30, 230          # Fast DDS: domain ids up to 232 map to valid ports


@contextlib.contextmanager
def private_domain(low: int = LOW, high: int = HIGH) -> Iterator[int]:
    """Hold a free ROS domain id; sets ROS_DOMAIN_ID in this process's environment meanwhile."""
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
        old = os.environ.get("ROS_DOMAIN_ID")
        os.environ["ROS_DOMAIN_ID"] = str(i)
        try:
            yield i
        finally:
            if old is None:
                os.environ.pop("ROS_DOMAIN_ID", None)
            else:
                os.environ["ROS_DOMAIN_ID"] = old
            f.close()
        return
    raise RuntimeError(f"no free ROS domain id in [{low}, {high}) on this machine")
