"""Exact repetition (issue 23): the same sweep file run twice gives the same trial records — every
metric, the trajectory sample by sample, what the display showed — because scripted sessions run
in lockstep sim time with the simulator holding between trials, each condition in a graph started
with its parameters, and every random draw seeded. 8 trials: 2 virtual subjects × 2 modes × 2
repetitions of the documented example (5 s trials). The first run is the session fixture
``repeated_sweep`` (tests/experiments/conftest.py), which test_sweeps.py checks as a sweep on workers."""
from __future__ import annotations

import csv

import pytest

from raspv_experiments.report import build_report
from raspv_experiments.session import read_jsonl
from raspv_experiments.sweep import run_sweep

pytestmark = [pytest.mark.integration, pytest.mark.slow]
VOLATILE = {"finished", "session", "run_dir", "bag"}          # where and when, not what happened


def records(out):
    recs = [r for f in sorted((out / "sessions" / "repeat").glob("*/trials.jsonl")) for r in read_jsonl(f)]
    return [{k: v for k, v in r.items() if k not in VOLATILE} for r in recs]


def test_the_same_sweep_twice_gives_identical_records(repeated_sweep, tmp_path):
    sweep, first_out, first_results = repeated_sweep
    outs = [first_out, tmp_path / "run2"]
    second_results = run_sweep(sweep, outs[1], workers=2, say=print)
    for results in (first_results, second_results):
        assert all(r["code"] == 0 for r in results), [r["log"] for r in results]
    first, second = (records(out) for out in outs)
    assert len(first) == 8 and all(r["status"] == "completed" for r in first)
    assert all(r["display"]["frames"] == 50 and r["display"]["own_share"] == 1.0 for r in first)   # 5 s at 10 Hz
    assert any(r["metrics"]["path_length_m"] > 1.0 for r in first)                    # they walked
    assert len(second) == len(first)
    for a, b in zip(first, second):
        assert a == b, (a["subject"], a["index"])
    # and the CSVs a researcher would diff
    csvs = []
    for k, out in enumerate(outs, 1):
        build_report([out], tmp_path / f"report{k}")
        with open(tmp_path / f"report{k}" / "trials.csv") as f:
            csvs.append([{c: v for c, v in row.items() if c not in VOLATILE} for row in csv.DictReader(f)])
    assert csvs[0] == csvs[1] and "spv.mode" in csvs[0][0]
