"""A warm spare of a node process: started in advance, imports done, waiting to take over (no rclpy).

Importing a node's module (NumPy, SciPy, OpenCV, Open3D, PyBullet, rclpy) is most of what a
node process does before its first message (``raspv bench restart``). For a node whose graph
entry says ``restart: true`` the launcher keeps one spare process that has done those imports
and waits on its stdin (``node_entry --spare``); when the node dies the spare is told to start
at once — one line on its stdin — and a new spare is prepared. A spare holds no ROS state
(no context, no node), so it cannot be seen on the graph. Cost: the spare's memory (≈ the
node's memory after its imports, 60–150 MB) while it waits.
"""
from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from dataclasses import dataclass


@dataclass
class WarmSpare:
    proc: subprocess.Popen
    reader: threading.Thread | None   # copies its output to the node's log and the terminal
    started_at: float                 # monotonic

    @property
    def alive(self) -> bool:
        """Still running (checked without reaping it, so its rusage can still be collected)."""
        if self.proc.returncode is not None:
            return False
        try:
            return os.waitid(os.P_PID, self.proc.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is None
        except ChildProcessError:
            return False

    def promote(self) -> bool:
        """Tell the spare to run the node now; False when it is gone (then start the node cold)."""
        if not self.alive:
            return False
        try:
            self.proc.stdin.write(f"{time.time()!r}\n".encode())
            self.proc.stdin.flush()
            self.proc.stdin.close()
        except (BrokenPipeError, OSError, ValueError):
            return False
        return True

    def discard(self, timeout_s: float = 2.0) -> tuple[int, float]:
        """End an unused spare (closing its stdin makes it exit; SIGKILL after ``timeout_s``).
        Returns its (peak RSS KiB, CPU s) for the launcher's resource table."""
        try:
            if self.proc.stdin and not self.proc.stdin.closed:
                self.proc.stdin.close()
        except OSError:
            pass
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                pid, status, usage = os.wait4(self.proc.pid, os.WNOHANG)
            except ChildProcessError:
                return 0, 0.0
            if pid:
                self.proc.returncode = os.waitstatus_to_exitcode(status)
                return int(usage.ru_maxrss), usage.ru_utime + usage.ru_stime
            time.sleep(0.02)
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        try:
            _, status, usage = os.wait4(self.proc.pid, 0)
        except ChildProcessError:
            return 0, 0.0
        self.proc.returncode = os.waitstatus_to_exitcode(status)
        return int(usage.ru_maxrss), usage.ru_utime + usage.ru_stime
