"""What the launcher does with a node's output (no rclpy): every line goes to the node's log
file; the terminal gets the same lines except Python tracebacks, each of which becomes one line
naming the exception and the log file that holds the full text.

Log files live in ``$ROS_LOG_DIR`` (else ``$ROS_HOME/log``, else ``~/.ros/log``, as ROS 2 does)
under ``raspv_launch_<date>_<pid>/<node>.log``; a restarted node appends to its file.
"""
from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Callable, IO

TRACEBACK_START = "Traceback (most recent call last):"
IGNORED_START = "Exception ignored in"          # Python's report of an error in __del__ & co.
_CHAIN_LINES = ("During handling of the above exception", "The above exception was the direct cause",
                TRACEBACK_START)


def ros_log_root(env: dict[str, str] | os._Environ = os.environ) -> Path:
    """Where ROS 2 keeps logs: ``$ROS_LOG_DIR``, else ``$ROS_HOME/log``, else ``~/.ros/log``."""
    if env.get("ROS_LOG_DIR"):
        return Path(env["ROS_LOG_DIR"]).expanduser()
    if env.get("ROS_HOME"):
        return Path(env["ROS_HOME"]).expanduser() / "log"
    return Path.home() / ".ros" / "log"


def new_launch_log_dir(env: dict[str, str] | os._Environ = os.environ) -> Path:
    """A fresh directory for one launch's node logs (created)."""
    root = ros_log_root(env)
    path = root / f"raspv_launch_{time.strftime('%Y-%m-%d-%H-%M-%S')}_{os.getpid()}"
    path.mkdir(parents=True, exist_ok=True)
    return path


class TracebackSummariser:
    """Turns a stream of output lines into what a person should see: each Python traceback
    (chained ones included, and Python's "Exception ignored in …" reports) is replaced by one
    line, ``raised <exception line> (full traceback in <log>)``.

    ``quiet(exception_line, ignored)`` → True hides even that line (e.g. the KeyboardInterrupt
    of a node the launcher is stopping); ``ignored`` is True for "Exception ignored in" reports.
    """

    def __init__(self, log_hint: str, quiet: Callable[[str, bool], bool] = lambda _line, _ignored: False) -> None:
        self.log_hint = log_hint
        self.quiet = quiet
        self._state = "text"              # text | traceback | after (an exception line, chaining may follow)
        self._ignored = False
        self.hidden = 0                   # lines kept off the terminal

    def feed(self, line: str) -> str | None:
        """The line to show for ``line`` (None: show nothing)."""
        stripped = line.strip()
        if self._state == "after":
            if stripped == "" or line.startswith(_CHAIN_LINES):
                self._state = "after" if stripped == "" else "traceback"
                self.hidden += 1
                return None
            self._state = "text"
        if self._state == "text":
            if stripped == TRACEBACK_START or line.startswith(IGNORED_START):
                self._state = "traceback"
                self._ignored = line.startswith(IGNORED_START)
                self.hidden += 1
                return None
            return line
        # inside a traceback: indented frames and code, chaining lines; the first other line
        # is the exception
        self.hidden += 1
        if stripped == "" or line[:1].isspace() or line.startswith(_CHAIN_LINES):
            return None
        self._state = "after"
        if self.quiet(stripped, self._ignored):
            return None
        return f"raised {stripped} (full traceback in {self.log_hint})"

    def flush(self) -> str | None:
        """At the end of the stream: a traceback cut short before its exception line."""
        if self._state == "traceback":
            self._state = "text"
            return f"printed a traceback that ended early (full text in {self.log_hint})"
        self._state = "text"
        return None


class NodeLog:
    """A node's log file, appended to across restarts; ``write`` is thread-safe enough for one
    reader thread per node (each line is written with one call)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._file: IO[str] = open(path, "a", encoding="utf-8", errors="replace", buffering=1)

    def write(self, line: str) -> None:
        try:
            self._file.write(line + "\n")
        except (OSError, ValueError):     # disk full or closed: the terminal still has the line
            pass

    def mark(self, text: str) -> None:
        self.write(f"--- {time.strftime('%H:%M:%S')} {text} ---")

    def close(self) -> None:
        try:
            self._file.close()
        except OSError:
            pass
