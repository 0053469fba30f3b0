"""Repeated-measures statistics against scipy, and the report's CSV and HTML from trial records."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from scipy import stats

from raspv_experiments.report import build_report, find_records, tidy_rows, ReportError
from raspv_experiments.repeated_measures import compare_conditions, holm, wilson_interval
from raspv_experiments.session import append_jsonl


def test_holm():
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert holm([0.5, float("nan"), 0.01]) == pytest.approx([0.5, float("nan"), 0.02], nan_ok=True)


def test_friedman_and_wilcoxon_match_scipy():
    rng = np.random.default_rng(4)
    subjects = [f"S{i:02d}" for i in range(1, 9)]
    values = {}
    for i, s in enumerate(subjects):
        base = rng.normal(30, 5)
        for c, shift in (("a", 0.0), ("b", 4.0), ("c", 8.0)):
            values[(s, c)] = list(base + shift + rng.normal(0, 2, size=3))
    res = compare_conditions("time", values, ["a", "b", "c"])
    table = np.array([[np.median(values[(s, c)]) for c in "abc"] for s in subjects])
    f = stats.friedmanchisquare(*table.T)
    assert res.friedman_statistic == pytest.approx(f.statistic) and res.friedman_p == pytest.approx(f.pvalue)
    pairs = {(p.a, p.b): p for p in res.pairs}
    w = stats.wilcoxon(table[:, 0], table[:, 2])
    assert pairs[("a", "c")].p == pytest.approx(w.pvalue)
    assert pairs[("a", "c")].p_holm == pytest.approx(min(1.0, 3 * min(p.p for p in res.pairs)))
    assert res.note == ""                                       # 8 subjects: tests can show a difference


def test_small_samples_incomplete_subjects_and_ties():
    values = {("S1", "a"): [1.0], ("S1", "b"): [2.0], ("S2", "a"): [1.0], ("S2", "b"): [3.0], ("S3", "a"): [1.0]}
    res = compare_conditions("x", values, ["a", "b"])
    assert res.subjects == ["S1", "S2"]                        # S3 lacks b: complete cases only
    assert "cannot give p < 0.5" in res.note
    tied = compare_conditions("y", {("S1", "a"): [1.0], ("S1", "b"): [1.0], ("S2", "a"): [2.0], ("S2", "b"): [2.0]},
                              ["a", "b"])
    assert tied.pairs[0].note == "no difference in any subject" and math.isnan(tied.pairs[0].p)
    assert "no test possible" in compare_conditions("z", {("S1", "a"): [1.0], ("S1", "b"): [2.0]}, ["a", "b"]).note
    lo, hi = wilson_interval(3, 10)
    assert lo == pytest.approx(0.1078, abs=1e-3) and hi == pytest.approx(0.6032, abs=1e-3)


def fake_session(root, subject, times, policy=None):
    """trials.jsonl of a session with completed trials (condition → list of completion times);
    ``policy``: a virtual patient's."""
    path = root / "example" / subject / "trials.jsonl"
    path.parent.mkdir(parents=True)
    index = 0
    for cond, ts in times.items():
        for rep, t in enumerate(ts, start=1):
            index += 1
            ok = t < 30
            append_jsonl(path, {
                "protocol": "example", "subject": subject, "condition": cond, "task": "hallway", "block": 1,
                "index": index, "repetition": rep, "practice": False, "attempt": 1, "status": "completed",
                "world": None, "start": [1.0, 1.5, 0.0], "goal": {"x": 8.6, "y": 1.5, "radius": 0.8, "label": "end"},
                "time_limit_s": 30.0, "run_dir": "", "session": str(path.parent),
                "metrics": {"outcome": "goal" if ok else "time_limit", "success": ok, "completion_time_s": t,
                            "duration_s": t, "path_length_m": 7.0, "shortest_path_m": 6.8,
                            "path_efficiency": 0.97 if ok else float("nan"), "collisions": rep - 1,
                            "collided_with": ["box:crate"] * (rep - 1), "min_clearance_m": 0.2,
                            "head_rotation_deg": 10.0, "head_rotation_deg_per_s": 1.0},
                "trajectory": {"t": [0, 1], "x": [1.0, 2.0], "y": [1.5, 1.5], "yaw": [0, 0]}, "policy": policy})
    append_jsonl(path, {"protocol": "example", "subject": subject, "condition": "depth", "task": "hallway",
                        "index": index + 1, "repetition": 1, "practice": False, "attempt": 1, "status": "skipped",
                        "policy": policy})


def test_report_from_sessions(tmp_path):
    fake_session(tmp_path / "s", "S01", {"depth": [12.0, 11.0, 10.0], "downsampling": [25.0, 31.0, 22.0]})
    fake_session(tmp_path / "s", "S02", {"depth": [14.0, 13.0, 12.5], "downsampling": [29.0, 24.0, 40.0]})
    records, sessions = find_records([tmp_path / "s"])
    assert len(records) == 14 and len(sessions) == 2
    html_path = build_report([tmp_path / "s"], tmp_path / "report", "example")
    rows = list(csv.DictReader(open(tmp_path / "report" / "trials.csv")))
    assert len(rows) == 14 and {r["status"] for r in rows} == {"completed", "skipped"}
    assert rows[0]["collided_with"] == "" and rows[1]["collided_with"] == "box:crate"
    page = html_path.read_text()
    for name in ("completion_time", "collisions", "success_rate", "path_efficiency", "trajectories-hallway", "learning"):
        assert (tmp_path / "report" / "figures" / f"{name}.png").stat().st_size > 1000
        assert (tmp_path / "report" / "figures" / f"{name}.pdf").exists()
        assert f"figures/{name}.png" in page
    # two conditions: Wilcoxon only (Friedman needs three; test_report_renders_a_friedman_result)
    assert "Friedman: two conditions: the Wilcoxon test below is the comparison." in page and "χ²" not in page
    assert "Wilcoxon" in page and "cannot give p &lt; 0.5" in page
    assert "6/6 (100 %)" in page and "4/6 (67 %)" in page
    with pytest.raises(ReportError, match="no trial records"):
        build_report([tmp_path / "report"], tmp_path / "r2")
    assert [r["index"] for r in tidy_rows(records) if r["subject"] == "S01"] == list(range(1, 8))


def test_effect_sizes_and_bootstrap_intervals():
    from raspv_experiments.repeated_measures import bootstrap_median_ci, kendall_w, rank_biserial

    assert rank_biserial(np.array([1.0, 2.0, 3.0])) == 1.0 and rank_biserial(np.array([-1.0, -2.0])) == -1.0
    assert rank_biserial(np.array([1.0, -2.0, 3.0, 0.0])) == pytest.approx((1 + 3 - 2) / 6)   # ranks 1, 2, 3; zero out
    agree = {(f"S{i}", c): [float(k)] for i in range(6) for k, c in enumerate("abc")}          # everyone a < b < c
    res = compare_conditions("x", agree, ["a", "b", "c"])
    assert res.kendall_w == pytest.approx(1.0) and kendall_w(res.friedman_statistic, 6, 3) == pytest.approx(1.0)
    d = np.array([2.0, 3.0, 2.5, 4.0, 3.5, 1.0, 2.0, 3.0])
    lo, hi = bootstrap_median_ci(d)
    assert lo <= np.median(d) <= hi and (lo, hi) == bootstrap_median_ci(d)                        # seeded
    assert np.isnan(bootstrap_median_ci(d[:2])[0]) and bootstrap_median_ci(np.ones(5)) == (1.0, 1.0)


def test_ties_give_notes_not_scipy_warnings():
    import warnings

    values = {(f"S{i}", c): [1.0 if c != "c" else 2.0 + (i % 2)] for i in range(6) for c in "abc"}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = compare_conditions("tied", values, ["a", "b", "c"])
        tied = compare_conditions("all", {(f"S{i}", c): [1.0] for i in range(6) for c in "abc"}, ["a", "b", "c"])
    assert res.pairs[0].note == "no difference in any subject" and res.pairs[1].p == pytest.approx(0.03125)
    assert tied.friedman_note.startswith("all values tied")


def test_censored_times_kaplan_meier_and_log_rank():
    from raspv_experiments.survival import kaplan_meier, logrank

    # 3 of 5 reached the goal at 10, 12, 15 s; two ran out of time at 40 s (censored, not 40 s times)
    km = kaplan_meier([10, 12, 15, 40, 40], [True, True, True, False, False])
    assert km.still_going.tolist() == pytest.approx([0.8, 0.6, 0.4, 0.4]) and km.median_s == 15.0
    km2 = kaplan_meier([10, 40, 40, 40], [True, False, False, False])
    assert np.isnan(km2.median_s)                                # fewer than half got there: "not reached"
    r = logrank("fast", [10, 11, 12, 13, 14, 15], [True] * 6, "slow", [40] * 6, [False] * 6)
    assert r.p < 0.01
    assert logrank("a", [40, 40], [False, False], "b", [40], [False]).note


def test_report_sections_factors_warnings_and_display(tmp_path):
    import warnings

    for s in ("S01", "S02", "S03"):
        fake_session(tmp_path / "s", s, {"mode=depth": [12.0, 14.0], "mode=grey": [40.0, 35.0]})
    for f in (tmp_path / "s").rglob("trials.jsonl"):            # add the sweep's factors and the display record
        recs = [json.loads(l) for l in f.read_text().splitlines()]
        f.write_text("")
        for k, r in enumerate(recs):
            if r.get("status") == "completed":
                r["factors"] = {"spv.mode": r["condition"].split("=")[1]}
                share = 0.9 if (k == 0 and "S02" in str(f)) else 1.0
                r["display"] = {"device": "argus_ii", "phosphenes": 60, "phosphenes_shown": 58, "frames": 100,
                                "own_frames": int(100 * share), "own_share": share,
                                "fallbacks": {"mode:depth": {"frames": 10, "seconds": 1.0}} if share < 1 else {}}
            append_jsonl(f, r)
        (f.parent / "session.json").write_text(json.dumps({"protocol": "example", "subject": f.parent.name,
                                                           "factors": {"spv.mode": ["grey", "depth"]}}))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        page = build_report([tmp_path / "s"], tmp_path / "report").read_text()
    assert "Condition mode=grey never reached the goal (0/6)" in page                   # the baseline warning
    assert "Kaplan–Meier median completion time" in page and "not reached" in page and "log-rank" in page
    assert "rank-biserial r" in page and "Kendall" not in page.split("Statistics")[0]
    assert "<table class='subjects'>" in page and "S03" in page
    assert "figures/main_effects.png" in page and "figures/kaplan_meier.png" in page
    effects = page[page.index("Sweep factors"):]
    assert effects.index("<td>grey</td>") < effects.index("<td>depth</td>")             # levels in the sweep's order
    assert "90.00 %" in page and "mode:depth 10 frames / 1.00 s" in page               # a trial flagged
    assert "Empty: no trial reached the goal" not in page
    rows = list(csv.DictReader(open(tmp_path / "report" / "trials.csv")))
    assert rows[0]["spv.mode"] in ("depth", "grey") and rows[0]["phosphenes_shown"] == "58"
    lenient = build_report([tmp_path / "s"], tmp_path / "r2", share_threshold=0.8).read_text()
    assert "at least 80 %" in lenient


def test_report_renders_a_friedman_result(tmp_path):
    """Three conditions, six subjects: the page shows Friedman's χ², p and Kendall's W as scipy
    computes them on the subjects' medians."""
    rng = np.random.default_rng(7)
    times = {}
    for i in range(6):
        base = rng.uniform(8, 14)
        times[f"S{i + 1:02d}"] = {c: list(np.round(base + shift + rng.normal(0, 1.0, 3), 2))
                                  for c, shift in (("depth", 0.0), ("edges", 4.0), ("downsampling", 8.0))}
        fake_session(tmp_path / "s", f"S{i + 1:02d}", times[f"S{i + 1:02d}"])
    page = build_report([tmp_path / "s"], tmp_path / "report", "example").read_text()
    conditions = ["depth", "edges", "downsampling"]
    table = np.array([[np.median(times[s][c]) for c in conditions] for s in sorted(times)])
    f = stats.friedmanchisquare(*table.T)
    w = f.statistic / (6 * (3 - 1))
    section = page.split("<h3>completion time [s]</h3>")[1].split("<h3>")[0]
    assert f"Friedman χ²(2) = {f.statistic:.2f}, p = {f.pvalue:.3g}, Kendall's W = {w:.2f}." in section, section[:600]
    assert f.pvalue < 0.05                       # the shifts are clear: the test is not a formality


def test_virtual_patients_of_two_policies_are_not_pooled_silently_and_are_called_virtual(tmp_path):
    fake_session(tmp_path / "s", "scripted-navigate-1", {"depth": [12.0], "downsampling": [25.0]}, policy="navigate")
    fake_session(tmp_path / "s", "scripted-learned-1", {"depth": [40.0], "downsampling": [40.0]}, policy="learned")
    with pytest.raises(ReportError, match=r"2 kinds of subject: virtual patient \(learned\): 3 records; "
                                          r"virtual patient \(navigate\): 3 records"):
        build_report([tmp_path / "s"], tmp_path / "report")
    page = build_report([tmp_path / "s"], tmp_path / "report", pool=True).read_text()
    assert "pools 2 kinds of subject" in page and "virtual patients</b> (scripted policy learned, navigate" in page
    assert "figures/learning.png" not in page                      # one repetition: nothing to learn across
    alone = build_report([tmp_path / "s" / "example" / "scripted-navigate-1"], tmp_path / "r1").read_text()
    assert "All subjects were <b>virtual patients</b> (scripted policy navigate" in alone and "pools" not in alone


def test_a_report_of_people_does_not_call_them_virtual(tmp_path):
    fake_session(tmp_path / "s", "S01", {"depth": [12.0, 11.0], "downsampling": [25.0, 31.0]})
    page = build_report([tmp_path / "s"], tmp_path / "report").read_text()
    assert "virtual patients" not in page and "figures/learning.png" in page


def test_paired_binary_success_uses_cochrans_q_and_mcnemar():
    from raspv_experiments.paired_binary import cochran_q, mcnemar_exact
    from raspv_experiments.repeated_measures import compare_conditions

    table = np.array([[1, 1, 0], [1, 0, 0], [1, 1, 1], [1, 0, 0]])
    q, p = cochran_q(table)                       # by hand: 2 (3·21 − 49) / (3·7 − 15) = 14/3
    assert q == pytest.approx(14 / 3) and p == pytest.approx(math.exp(-7 / 3))       # χ²(2) tail: e^(−Q/2)
    rng = np.random.default_rng(3)
    a, b = rng.integers(0, 2, 40), rng.integers(0, 2, 40)
    only_a, only_b, p2 = mcnemar_exact(a, b)
    assert cochran_q(np.column_stack([a, b]))[0] == pytest.approx((only_a - only_b) ** 2 / (only_a + only_b))
    assert p2 == pytest.approx(stats.binomtest(only_a, only_a + only_b).pvalue)
    # one trial per subject and condition: the success comparison is McNemar's, not Wilcoxon's
    values = {(f"S{i}", c): [float(v)] for i, row in enumerate(table) for c, v in zip(("x", "y", "z"), row)}
    res = compare_conditions("success rate", values, ["x", "y", "z"], proportion=True)
    assert res.binary and res.friedman_statistic == pytest.approx(14 / 3) and len(res.pairs) == 3
    xz = res.pairs[1]
    assert (xz.a, xz.b) == ("x", "z") and xz.p == pytest.approx(0.25) and xz.median_difference == pytest.approx(0.75)
    # repeated trials give fractions: the rank tests stay
    repeated = {k: v * 2 for k, v in values.items()}
    assert not compare_conditions("success rate", repeated, ["x", "y", "z"], proportion=True).binary


def test_the_report_names_mcnemar_for_one_trial_per_condition(tmp_path):
    for i in range(6):
        fake_session(tmp_path / "s", f"S{i + 1:02d}", {"depth": [12.0], "downsampling": [25.0 if i < 2 else 35.0]})
    page = build_report([tmp_path / "s"], tmp_path / "report").read_text()
    section = page.split("<h3>success rate</h3>")[1].split("<h3>")[0].split("<h2>")[0]
    assert "McNemar exact p" in section and "4 succeeded only in depth, 0 only in downsampling" in section
    assert "Wilcoxon" not in section
