"""The experimenter's terminal: one status line redrawn in place and single-key commands
(:mod:`raspv_experiments.session_control` holds the logic; this is only I/O).

On a terminal, keys are read without Enter (cbreak mode, restored at exit). Elsewhere (a
pipe, a sweep worker) there are no keys and each change of phase is printed as a line.
"""
from __future__ import annotations

import os
import select
import shutil
import sys
import threading
from typing import Callable, TextIO

from raspv_experiments.session_control import ViewState, status_line


class TerminalView:
    def __init__(self, on_key: Callable[[str], None] | None = None, out: TextIO | None = None,
                 interactive: bool | None = None) -> None:
        self.out = out or sys.stdout
        self.on_key = on_key
        self.interactive = (self.out.isatty() and sys.stdin.isatty()) if interactive is None else interactive
        self._last_phase = ""
        self._saved = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if self.interactive and on_key is not None:
            self._start_keys()

    def _start_keys(self) -> None:
        import termios
        import tty

        fd = sys.stdin.fileno()
        try:
            self._saved = termios.tcgetattr(fd)
            tty.setcbreak(fd)
        except termios.error:
            self._saved = None
            return
        self._thread = threading.Thread(target=self._read_keys, daemon=True, name="experimenter-keys")
        self._thread.start()

    def _read_keys(self) -> None:
        fd = sys.stdin.fileno()
        while not self._stop.is_set():
            ready, _, _ = select.select([fd], [], [], 0.1)
            if ready:
                ch = os.read(fd, 1).decode(errors="ignore")
                if ch and self.on_key is not None:
                    self.on_key("enter" if ch in "\r\n" else ch)

    def show(self, view: ViewState) -> None:
        if self.interactive:
            width = shutil.get_terminal_size((100, 20)).columns
            self.out.write("\r\x1b[2K" + status_line(view, width - 1))
            self.out.flush()
        elif view.phase != self._last_phase or view.phase == "finished":
            self.out.write(status_line(view, 200) + "\n")
            self.out.flush()
        self._last_phase = view.phase

    def say(self, text: str) -> None:
        """A line above the status line (kept in the scrollback)."""
        self.out.write(("\r\x1b[2K" if self.interactive else "") + text + "\n")
        self.out.flush()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        if self._saved is not None:
            import termios

            termios.tcsetattr(sys.stdin.fileno(), termios.TCSADRAIN, self._saved)
            self._saved = None
        if self.interactive:
            self.out.write("\n")
            self.out.flush()
