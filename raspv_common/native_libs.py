"""System libraries the binary wheels expect, supplied from wheels when the system lacks them.

Open3D and pyrealsense2 link ``libusb-1.0.so.0``. ``make install`` links the copy of the
``libusb-package`` wheel into the venv's ``lib/``; an environment made with ``pip install
raspv`` has no such link, so :func:`ensure_libusb` loads that copy into the process (globally,
under its soname) before either is imported, unless the system's loader already finds one.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import functools


@functools.cache
def ensure_libusb() -> str | None:
    """Make ``libusb-1.0.so.0`` loadable; the path loaded from the wheel, or None (the system's)."""
    try:
        ctypes.CDLL("libusb-1.0.so.0")
        return None
    except OSError:
        pass
    try:
        import libusb_package
    except ImportError:
        return None            # the import that needs it names the problem
    path = libusb_package.get_library_path()
    if path:
        ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
        return str(path)
    return None
