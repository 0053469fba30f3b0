"""The count sweep inside the study's range against the people's numbers (tools/count_sweep_vs_people.py,
raspv_experiments/human_reference.py): the % restored measure on known records, and the
documented power, trend and point-by-point comparison recomputed from the shipped rows (which a
stratified re-run in test_trend.py checks are what the code gives)."""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest

from raspv_experiments.human_reference import HUMAN_RESTORED, restored, restored_table
from raspv_experiments.quick_sweep import QuickTrialRecord

REPO = Path(__file__).resolve().parents[2]
FACTOR = "spv.num_phosphenes"


def _record(subject, level, time_s, collisions):
    return QuickTrialRecord(subject, f"n={level}", {FACTOR: str(level)}, "course", 1, True, time_s, time_s,
                            collisions, 20.0, level, 1.0)


def test_restored_is_the_share_of_the_gap_to_normal_vision():
    # 10×10: 70 s, 2 collisions; 26×26: 55 s, 1; normal vision 40 s: half the time gap and of the collisions
    records = [_record(s, 100, 70.0 + s % 2, 2) for s in range(1, 7)]
    records += [_record(s, 676, 55.0 + s % 2, 1) for s in range(1, 7)]
    rows = restored(records, FACTOR, ["100", "676"], {"course": 90.0}, {s: 40.0 + s % 2 for s in range(1, 7)},
                    resamples=500)
    by = {(r.measure, r.level): r for r in rows}
    assert by[("time_s", "100")].percent == 0.0
    assert math.isclose(by[("time_s", "676")].percent, 50.0) and math.isclose(by[("collisions", "676")].percent, 50.0)
    assert by[("time_s", "676")].human_simple == HUMAN_RESTORED["time_s"][(676, "simple")] == 59.2
    assert "| 676 | 50 [50, 50] | 59.2 | 50 [50, 50] | 90.2 |" in restored_table(rows)


@pytest.mark.slow                     # bootstrap of every trend step and the planner's shortest path: ~20-40 s loaded
def test_the_documented_comparison_with_the_people():
    """docs/experiments.md, "Inside the study's range"."""
    spec = importlib.util.spec_from_file_location("count_vs_people", REPO / "tools" / "count_sweep_vs_people.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    a = tool.analyse()
    assert a["subjects"] == 12 and a["shortest_m"] == pytest.approx(22.23, abs=0.01)
    assert a["gap_s"] == pytest.approx(34.2, abs=0.05) and a["sd_diff_s"] == pytest.approx(16.5, abs=0.05)
    p26, p18 = a["power"][676], a["power"][324]
    assert p26["dz"] == pytest.approx(1.22, abs=0.005) and p26["power"] == pytest.approx(0.97, abs=0.005)
    assert (p26["n80"], p26["n90"]) == (8, 10)
    assert p18["power"] == pytest.approx(0.85, abs=0.005) and (p18["n80"], p18["n90"]) == (11, 14)
    assert a["observed_dz"] == pytest.approx(0.54, abs=0.005)
    trends = {t.measure: t for t in a["trends"]}
    assert trends["time_s"].page_p == pytest.approx(0.003, abs=0.0005) and trends["success"].page_p > 0.3
    assert all(s.ci[0] <= 0 <= s.ci[1] for t in a["trends"] for s in t.steps)     # no step inside the range
    by = {(r.measure, r.level): r for r in a["restored"]}
    for level, people in (("324", 46.2), ("676", 59.2)):
        assert by[("time_s", level)].ci[1] < people                                  # below the people's, CI and all
    assert round(by[("time_s", "676")].percent) == 26 and round(by[("time_s", "324")].percent) == 22
    assert by[("time_s", "2500")].ci[0] > 0                                          # 50×50: CI above 0
