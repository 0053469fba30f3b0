"""Capture what PyBullet's C code prints on the process's stdout/stderr (plugin banners, URDF
warnings), so logs stay readable and callers can quote it when something fails."""
from __future__ import annotations

import contextlib
import ctypes
import os
import sys
import tempfile
from typing import Iterator


try:
    _LIBC = ctypes.CDLL(None)
except OSError:  # pragma: no cover - every Linux has a libc
    _LIBC = None


def _flush_c_streams() -> None:
    """Flush C stdio buffers so text printed inside the block lands in the capture."""
    if _LIBC is not None:
        _LIBC.fflush(None)


class Captured:
    text: str = ""


@contextlib.contextmanager
def captured_native_output() -> Iterator[Captured]:
    """Redirect file descriptors 1 and 2 to a temporary file while the block runs; the text
    is in the yielded object's ``text`` afterwards."""
    result = Captured()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError):
            pass
    _flush_c_streams()
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        saved = []
        try:
            for fd in (1, 2):
                try:
                    saved.append((fd, os.dup(fd)))
                    os.dup2(tmp.fileno(), fd)
                except OSError:
                    pass
            yield result
        finally:
            _flush_c_streams()
            for fd, copy in saved:
                os.dup2(copy, fd)
                os.close(copy)
            tmp.seek(0)
            result.text = tmp.read().decode(errors="replace")
