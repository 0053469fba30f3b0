"""A private ROS domain for each graph a sweep runs (no rclpy): a lock file per domain id in
``$TMPDIR/raspv-domains`` — the same files the test harness uses
(:func:`raspv_bringup.testing.claim_private_domain`), so sweeps, tests and other users'
graphs on one machine never share a domain. Released when the context ends.
"""
from __future__ import annotations

import contextlib
import os
from typing import Iterator

from raspv_common.ros_domains import HIGH, LOW, lock_free_domain


@contextlib.contextmanager
def private_domain(low: int = LOW, high: int = HIGH) -> Iterator[int]:
    """Hold a free ROS domain id; sets ROS_DOMAIN_ID in this process's environment meanwhile."""
    i, f = lock_free_domain(low, high)
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
