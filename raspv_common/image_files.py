"""Decoding image files users name, without OpenCV's own log lines (no ROS imports).

``cv2.imread``/``cv2.imdecode`` print ``[ERROR:0@0.179] global loadsave.cpp … imdecode_ …`` or
``[ WARN:…] imread_ …`` on stderr before returning None for a garbage or truncated file; the
caller then raises its own one-line error, so that log line is noise in front of it.
:func:`decode_image_file` reads and decodes with OpenCV's log silenced for the call.
"""
from __future__ import annotations

import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

_LOCK = threading.Lock()        # the log level is process-wide: restore it once, in order


@contextmanager
def opencv_silenced() -> Iterator[None]:
    """OpenCV's log off for the block (its previous level restored after)."""
    log = cv2.utils.logging
    with _LOCK:
        previous = log.getLogLevel()
        log.setLogLevel(log.LOG_LEVEL_SILENT)
        try:
            yield
        finally:
            log.setLogLevel(previous)


def decode_image_file(path: str | Path, flags: int = cv2.IMREAD_UNCHANGED) -> np.ndarray | None:
    """The decoded image of ``path`` (as ``cv2.imread`` with ``flags``), or None when the file
    is missing, unreadable or not an image OpenCV decodes — with nothing printed."""
    try:
        data = np.fromfile(str(path), dtype=np.uint8)
    except OSError:
        return None
    if not data.size:
        return None
    with opencv_silenced():
        return cv2.imdecode(data, flags)
