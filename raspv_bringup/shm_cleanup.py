"""Shared-memory segments left by killed nodes (no rclpy): the ``fastdds shm clean`` of RASPV.

Fast DDS's shared-memory transport gives every participant (one per node process) a segment
``/dev/shm/fastrtps_<16 hex>`` (~0.5 MB touched of its 16 MB, `config/fastdds_shm.xml`) and a
companion ``…_el`` file on which the owner holds an exclusive ``flock`` while it lives. A
process that exits normally removes both; one killed with SIGKILL leaves them, and they stay in
RAM (a day of tests here left 270 of them, 0.5 GB). A segment is stale when no live process
holds the lock on its ``_el`` file (locks die with their process, ``/proc/locks`` lists the
held ones) and it is older than :data:`MIN_AGE_S` (a participant being created has not locked
it yet). Removing the names is safe for processes that still map the segment (their mapping
stays), as with Fast DDS's own tool. Port segments (``fastrtps_port<N>``, shared by every
process that talks on the port, a few kB each) are left alone.
"""
from __future__ import annotations

import os
import re
import time
from dataclasses import dataclass
from pathlib import Path

SHM_DIR = Path("/dev/shm")
MIN_AGE_S = 2.0     # [s]; a participant locks its segment microseconds after creating it
_SEGMENT = re.compile(r"^fastrtps_[0-9a-f]{16}$")


@dataclass(frozen=True)
class Cleanup:
    removed: int
    bytes_freed: int

    def describe(self) -> str:
        return (f"removed {self.removed} shared-memory segment(s) ({self.bytes_freed / 1e6:.1f} MB) left by "
                "killed processes")


def held_locks(proc_locks: str = "/proc/locks") -> set[tuple[int, int, int]]:
    """(major, minor, inode) of every file a live process holds a lock on."""
    held = set()
    try:
        text = Path(proc_locks).read_text()
    except OSError:
        return held
    for line in text.splitlines():
        fields = line.split()
        # "1: FLOCK  ADVISORY  WRITE 10877 00:1b:459406 0 EOF" (blocked waiters have "->")
        if len(fields) < 6 or fields[1] == "->":
            continue
        try:
            major, minor, inode = fields[5].split(":")
            held.add((int(major, 16), int(minor, 16), int(inode)))
        except ValueError:
            continue
    return held


def stale_segments(shm_dir: Path = SHM_DIR, now: float | None = None, min_age_s: float = MIN_AGE_S,
                   proc_locks: str = "/proc/locks") -> list[Path]:
    """Participant segments whose owner is dead (see the module's docstring)."""
    now = time.time() if now is None else now
    held = held_locks(proc_locks)
    out = []
    try:
        names = os.listdir(shm_dir)
    except OSError:
        return out
    for name in names:
        if not _SEGMENT.match(name):
            continue
        segment, lock = Path(shm_dir) / name, Path(shm_dir) / f"{name}_el"
        try:
            st = lock.stat()
        except OSError:
            continue                                  # no lock file: not ours to judge
        if (os.major(st.st_dev), os.minor(st.st_dev), st.st_ino) in held or now - st.st_mtime < min_age_s:
            continue
        out.append(segment)
    return sorted(out)


def remove_stale_segments(shm_dir: Path = SHM_DIR, min_age_s: float = MIN_AGE_S) -> Cleanup:
    """Remove the stale participant segments and their lock files; what was freed."""
    removed = freed = 0
    for segment in stale_segments(shm_dir, min_age_s=min_age_s):
        try:
            size = segment.stat().st_blocks * 512
            segment.unlink()
        except OSError:
            continue                                  # gone meanwhile, or not ours to remove
        Path(f"{segment}_el").unlink(missing_ok=True)
        removed, freed = removed + 1, freed + size
    return Cleanup(removed, freed)
