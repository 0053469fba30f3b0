"""Freed message buffers kept for the next message instead of returned to the kernel (no rclpy).

A node handles buffers of 0.5–5 MB many times a second (images, depth, point clouds, serialised
messages). glibc's malloc serves blocks above its *mmap threshold* with a fresh mapping that it
unmaps on free, and returns the top of its heap to the kernel above its *trim threshold*; both
thresholds move with the sizes it has seen. Depending on the order of allocations a process
settles in one of two states — measured in the foxglove node forwarding 150 messages/s (50 MB/s):
128 or 28 000 page faults per second, 7 % or 12 % of a core (the kernel zeroing each new page) —
and the scene node took 2 400–9 200 faults/s. :func:`keep_freed_buffers` fixes both thresholds
so that blocks up to :data:`MMAP_THRESHOLD_BYTES` come from the heap and up to
:data:`TRIM_THRESHOLD_BYTES` of free heap stay mapped for reuse (per malloc arena).
"""
from __future__ import annotations

import ctypes

M_TRIM_THRESHOLD = -1          # glibc's mallopt parameter numbers (malloc.h)
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD_BYTES = 8 << 20     # blocks below this come from the heap, not a mapping of their own
TRIM_THRESHOLD_BYTES = 32 << 20    # free heap kept mapped before returning it to the kernel


def keep_freed_buffers() -> bool:
    """Set both thresholds (glibc; call once, early); whether it was done (False: not glibc)."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))
