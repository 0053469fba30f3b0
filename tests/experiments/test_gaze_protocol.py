"""A 2-condition protocol, gaze-locked vs gaze-contingent phosphenes, run with a scripted subject
whose eyes move (the scripted gaze model, switched on because the conditions use the gaze); the
trial records and the report carry the gaze metrics. Real processes: ``raspv experiment run``
(sim in lockstep, headless spv, the subject node) and ``raspv experiment report``."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from raspv_experiments.session import read_jsonl

from .test_experiment_flow import finish, raspv

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_locked_vs_contingent_with_a_scripted_subject_and_its_gaze_metrics(example_doc, write_protocol, tmp_path,
                                                                          ros_domain):
    doc = example_doc
    doc["name"] = "gaze_study"
    doc["conditions"] = {"locked": {"spv": {"gaze_mode": "locked"}},
                         "contingent": {"spv": {"gaze_mode": "contingent"}}}
    doc["graph"]["spv"]["ros__parameters"]["mode"] = "depth"
    doc["design"].update(repetitions=1, order="fixed")
    doc["tasks"]["hallway"]["time_limit"] = 5
    protocol = write_protocol(doc)
    out = tmp_path / "sessions"
    finish(raspv("experiment", "run", str(protocol), "--subject", "scripted:wander_avoid:1", "--out", str(out)),
           timeout=240)
    records = read_jsonl(out / "gaze_study" / "scripted-wander_avoid-1" / "trials.jsonl")
    assert [r["condition"] for r in records] == ["locked", "contingent"]
    for r in records:
        assert r["params"] == {"spv": {"gaze_mode": r["condition"]}}
        g = r["gaze"]
        # 5 s of sim time at 120 Hz from the model: ~16 fixations of ~0.28 s, saccades of a few degrees
        assert g["samples"] > 400 and 4 <= g["fixations"] <= 30 and g["saccades"] >= 3
        assert 1.0 < g["mean_saccade_amplitude_deg"] < 15.0 and 0.8 <= g["valid_share"] <= 1.0
        run_dir = Path(r["run_dir"])                     # the trial's log, in this session's folder
        assert run_dir.is_relative_to(out / "gaze_study") and (run_dir / "gaze.csv").is_file()
    # the same subject's eyes are reseeded per trial: the two trials' gaze differs
    assert records[0]["gaze"] != records[1]["gaze"]
    finish(raspv("experiment", "report", str(out), "-o", str(tmp_path / "report")), timeout=120)
    html = (tmp_path / "report" / "report.html").read_text()
    assert "<h2>Eye gaze</h2>" in html and "mean saccade amplitude [deg]" in html and "gaze valid share" in html
    csv_head = (tmp_path / "report" / "trials.csv").read_text().splitlines()[0].split(",")
    assert {"gaze_fixations", "gaze_mean_saccade_amplitude_deg", "gaze_valid_share"} <= set(csv_head)
    assert all(math.isfinite(r["gaze"]["mean_fixation_s"]) for r in records)
