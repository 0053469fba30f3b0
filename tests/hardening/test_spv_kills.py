"""The spv node killed again and again with a headset watching (issue 36): the bridge's no-data
ring within 300 ms every time, even when the warm spare has registered under the same name before
the ring was due (that case took 1.04 s: the replacement counted as the producer, alive, so the
1-s late bound applied). `raspv bench spv-kills` runs the same measurement 20 times (its figures
in docs/running.md); this test runs it 5 times to stay within the suite's time."""
from __future__ import annotations

import re

import pytest

from raspv_bench.spv_kills import kill_spv

pytestmark = [pytest.mark.integration, pytest.mark.slow]

KILLS = 5
TARGET_S = 0.3
# Margin for a 2-core machine loaded by other test runs: the ring is drawn by a 20 Hz timer of the
# bridge (50 ms) and the bridge, the spare's start and the client (this process, not real-time)
# share two cores; measured rings under load 2-6: 130-210 ms, 20-kill runs at load 14-36: gaps
# median 138 ms, a client held up 245 ms by the load alone; with spv starting at normal priority
# (7 Dec, 88 kills at load 5-15) rings 86-145 ms, gaps over 300 ms in 3 (340-341 ms: the bridge and
# the new spv stalled at once, docs/limits.md). The bug this guards against took 1.04 s.
MARGIN_S = 0.2


def test_the_ring_follows_every_kill_of_spv_within_300_ms(ros_domain):
    figures, output = kill_spv(KILLS, report=print)
    assert len(figures) == KILLS
    rings = [round(f.ring_s, 3) for f in figures]           # made after the kill (stamp), the client's lag aside
    gaps = [round(f.gap_s, 3) for f in figures]
    print(f"rings {rings} s, longest gaps {gaps} s, client lags {[round(f.lag_s, 3) for f in figures]} s")
    assert max(rings) <= TARGET_S + MARGIN_S, (rings, output[-3000:])
    assert max(gaps) <= TARGET_S + MARGIN_S, (gaps, output[-3000:])
    # every ring judged the dead process, never "alive but late" (the bug's line); a new process
    # whose first frames stall while it starts shows the ring once more (its probation)
    lines = re.findall(r"no frames from the spv node \((.*)\): showing", output)
    print("\n".join(lines))
    assert sum("its node gone" in line for line in lines) >= KILLS, lines
    assert all("its node gone" in line or "stalled" in line for line in lines), lines
    # the replacement's node name not known yet is not a producer: no alive topic for it
    assert "topic seen:" not in output, output[-500:]
    assert "Traceback" not in output
