"""Shared-memory segments of killed processes are removed, those of live ones kept (real flock
locks held by real processes, in a private folder standing in for /dev/shm)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from raspv_bringup.shm_cleanup import remove_stale_segments, stale_segments

HOLDER = """
import fcntl, sys, time
seg, lock = sys.argv[1], sys.argv[1] + "_el"
open(seg, "wb").write(b"x" * 8192)
fd = open(lock, "wb")
fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)     # as a Fast DDS participant does
print("locked", flush=True)
time.sleep(600)
"""


def _holder(path):
    p = subprocess.Popen([sys.executable, "-c", HOLDER, str(path)], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "locked"
    return p


def test_only_segments_whose_owner_died_are_removed(tmp_path):
    live, dead = tmp_path / "fastrtps_00000000000000aa", tmp_path / "fastrtps_00000000000000bb"
    port = tmp_path / "fastrtps_port7000"
    port.write_bytes(b"p")
    alive, killed = _holder(live), _holder(dead)
    try:
        os.kill(killed.pid, signal.SIGKILL)
        killed.wait(timeout=10)
        assert stale_segments(tmp_path, min_age_s=60) == []                   # too young to judge
        assert stale_segments(tmp_path, now=time.time() + 5, min_age_s=1) == [dead]
        cleanup = remove_stale_segments(tmp_path, min_age_s=0)
        assert cleanup.removed == 1 and cleanup.bytes_freed >= 8192
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, f"{live.name}_el", port.name])
    finally:
        alive.kill()
        alive.wait(timeout=10)
    assert remove_stale_segments(tmp_path, min_age_s=0).removed == 1          # its owner is gone now
