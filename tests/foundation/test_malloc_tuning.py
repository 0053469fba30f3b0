"""Nodes keep freed message buffers for the next message (raspv_common.malloc_tuning): the same
stream of image-sized allocations costs a fraction of the page faults."""
from __future__ import annotations

import subprocess
import sys

import pytest

CHILD = """
import resource, sys
import numpy as np
from raspv_common.malloc_tuning import keep_freed_buffers
done = keep_freed_buffers() if sys.argv[1] == "kept" else None
faults = lambda: resource.getrusage(resource.RUSAGE_SELF).ru_minflt
before = faults()
for i in range(300):                    # serialised images of varying size, and a decoded frame
    raw = bytes(640_000 + (i % 7) * 100_000)
    frame = np.zeros((480, 640, 3), np.uint8) + (i % 200)
    del raw, frame
print(done, faults() - before)
"""


def _faults(how: str) -> tuple[str, int]:
    out = subprocess.run([sys.executable, "-c", CHILD, how], capture_output=True, text=True, timeout=120, check=True)
    done, faults = out.stdout.split()
    return done, int(faults)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc")
def test_freed_buffers_are_reused_instead_of_faulted_in_again():
    done, kept = _faults("kept")
    _, plain = _faults("plain")
    assert done == "True"
    # 300 buffers of 0.6-1.2 MB: each a new mapping without (~250 faults each); reused with
    assert plain > 20_000 and kept < plain / 20, (kept, plain)
