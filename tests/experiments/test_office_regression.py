"""Regression of the default virtual patient (navigate) on the office task (experiments/office_navigation.yaml,
from the corridor to the bin): following the path overlay over Chess + Wall-Obstacles must reach the bin
more often than with downsampling. Runs as a sweep (lockstep, headless, worker processes) — which repeats
exactly, so the outcome is the same on every run (it failed 1 of 6 clean-clone runs before). 25 s of
simulated time per trial: the path overlay reaches the bin at 16.4 and 17.6 s in every run; downsampling
did not within 40 s either (6-9 collisions), and its trials run to the limit (40 s: 2 x 15 s more)."""
from __future__ import annotations

import pytest
import yaml

from raspv_experiments.session import read_jsonl
from raspv_experiments.sweep import load_sweep, run_sweep

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_path_overlay_beats_downsampling_in_success_rate(tmp_path):
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump({
        "name": "office_regression", "protocol": "office_navigation", "policy": "navigate", "subjects": 2,
        "conditions": ["chess_wall_obstacles_path", "downsampling"], "repetitions": 1,
        "graph_overrides": ["sim.width:=160", "sim.height:=120", "sim.renderer:=tiny"], "time_limit": 25}))
    sweep = load_sweep(tmp_path / "sweep.yaml")
    out = tmp_path / "out"
    results = run_sweep(sweep, out, workers=2, say=print)
    records = [r for res in results for r in read_jsonl(out / "sessions" / "office_regression" / res["subject"] /
                                                        "trials.jsonl")]
    rate = {}
    for cond in ("chess_wall_obstacles_path", "downsampling"):
        trials = [r for r in records if r["condition"] == cond and r["status"] == "completed"]
        assert len(trials) == 2
        rate[cond] = sum(r["metrics"]["success"] for r in trials) / len(trials)
        print(cond, [(r["metrics"]["outcome"], r["metrics"]["completion_time_s"], r["metrics"]["collisions"],
                      r["metrics"]["path_efficiency"]) for r in trials])
    assert rate["chess_wall_obstacles_path"] > rate["downsampling"], rate
