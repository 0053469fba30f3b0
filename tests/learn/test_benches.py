"""The quick modes of `raspv bench twin` and `raspv bench learned` (figures printed, peers run)."""
from __future__ import annotations

import re

from raspv_bringup.cli import main as raspv


def test_bench_twin_quick_prints_frames_per_second_beside_dynaphos(capsys):
    assert raspv(["bench", "twin", "--quick"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"target <= 0.0001 of the peak per pixel: (met|MISSED)", out)
    assert re.search(r"render forward\s+\d+ frames/s", out) and "temporal recurrence" in out
    assert "dynaphos" in out and (re.search(r"the twin is [\d,]+x faster", out) or "not available" in out)


def test_bench_learned_quick_times_the_mode_beside_hand_designed_ones(capsys):
    assert raspv(["bench", "learned", "--quick", "--modes", "learned", "depth"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"learned\s+per camera frame: mode\s+[\d.]+ ms", out)
    assert re.search(r"depth\s+per camera frame", out)
    assert re.search(r"target learned <= 5 ms per camera frame on one core \(the mode's CPU time\): (met|MISSED)", out)
