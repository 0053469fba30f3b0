"""``raspv experiment report DIR...``: sessions and sweeps → a tidy CSV and an HTML report (no rclpy).

Every ``trials.jsonl`` under the given folders is read (sessions of ``raspv experiment run``
and of sweeps alike). Out come, in ``-o OUT``:

- ``trials.csv``   one row per trial record (tidy: one observation per row, one variable per
                   column; ``status`` says completed/skipped/repeated/interrupted, ``practice``
                   marks practice trials — the figures and tests use completed non-practice ones);
- ``report.html``  warnings (a baseline that never succeeds, pooled protocols), per-condition
                   summary, per-subject table, figures (``figures/*.png`` and ``*.pdf``), completion
                   times with the time limit as censoring (Kaplan–Meier, log-rank;
                   :mod:`raspv_experiments.survival`), repeated-measures statistics with effect sizes
                   and bootstrap intervals and their assumptions
                   (:mod:`raspv_experiments.repeated_measures`), sweep factors' main effects, what the
                   display showed (share of frames in each trial's own representation), and where the
                   data came from (sessions, software versions).

Sessions of different protocols (a different name or file content) are not pooled unless asked
(``pool=True``, ``--pool``): the report refuses, naming them. Pooled, a subject is
``protocol/subject``, so two protocols' S01 stay two subjects. Likewise sessions of different
kinds of subject — people, and each virtual patient's policy (``navigate``, ``learned`` …) —
are not one population: the report refuses to pool them unless asked, and says so when it does.
A report of virtual patients says so at its top; the learning figure (completion time across
repetitions) is left out when every condition ran once.
"""
from __future__ import annotations

import csv
import html
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from raspv_common.shown_share import DEFAULT_THRESHOLD
from raspv_experiments import report_sections as sections
from raspv_experiments.repeated_measures import ASSUMPTIONS, compare_conditions
from raspv_experiments.session import read_jsonl

COLUMNS = ["protocol", "subject", "condition", "task", "block", "index", "repetition", "practice", "attempt", "status",
           "outcome", "success", "completion_time_s", "duration_s", "time_limit_s", "path_length_m", "shortest_path_m",
           "path_efficiency", "collisions", "collided_with", "min_clearance_m", "head_rotation_deg",
           "head_rotation_deg_per_s", "phosphenes_shown", "device", "own_share", "fallback_frames", "gaze_fixations",
           "gaze_mean_fixation_s", "gaze_saccades", "gaze_mean_saccade_amplitude_deg", "gaze_valid_share", "world",
           "policy", "session", "run_dir"]
GAZE_MEASURES = [("gaze_fixations", "fixations"), ("gaze_mean_fixation_s", "mean fixation [s]"),
                 ("gaze_saccades", "saccades"), ("gaze_mean_saccade_amplitude_deg", "mean saccade amplitude [deg]"),
                 ("gaze_valid_share", "gaze valid share")]
MEASURES = [("completion_time_s", "completion time [s]", False), ("collisions", "collisions", False),
            ("path_efficiency", "path efficiency", False), ("min_clearance_m", "minimum clearance [m]", False),
            ("head_rotation_deg_per_s", "head rotation [deg/s]", False), ("success", "success rate", True)]


class ReportError(Exception):
    """Nothing to report on, or an unreadable input; the message says which."""


def find_records(dirs: list[Path]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(trial records, session infos) of every trials.jsonl under ``dirs``."""
    records, sessions = [], []
    for d in dirs:
        d = Path(d)
        if not d.exists():
            raise ReportError(f"{d}: no such folder")
        files = [d] if d.is_file() else sorted(d.rglob("trials.jsonl"))
        for f in files:
            recs = read_jsonl(f)
            records += recs
            info_path = f.parent / "session.json"
            info = {}
            if info_path.exists():
                try:
                    info = json.loads(info_path.read_text())
                except json.JSONDecodeError:
                    info = {}
            sessions.append({"folder": str(f.parent), "trials": len(recs), **{k: info.get(k) for k in
                             ("protocol", "subject", "subject_kind", "policy", "created", "software", "protocol_sha256",
                              "factors")}})
    if not records:
        raise ReportError(f"no trial records (trials.jsonl) under {', '.join(map(str, dirs))}")
    return records, sessions


def protocols_of(records: list[dict[str, Any]], sessions: list[dict[str, Any]]) -> dict[str, set[str]]:
    """Protocol name → the sha256 prefixes of its files among the sessions (a name run from two
    different files is two protocols)."""
    out: dict[str, set[str]] = {}
    for s in sessions:
        if s.get("protocol"):
            out.setdefault(str(s["protocol"]), set()).add(str(s.get("protocol_sha256") or "")[:12])
    for r in records:
        out.setdefault(str(r.get("protocol")), set())
    return out


def subject_kinds(records: list[dict[str, Any]]) -> dict[str, int]:
    """Kind of subject → its number of trial records: ``person``, or ``virtual patient (POLICY)``."""
    out: dict[str, int] = {}
    for r in records:
        kind = f"virtual patient ({r['policy']})" if r.get("policy") else "person"
        out[kind] = out.get(kind, 0) + 1
    return out


def check_pooling(records: list[dict[str, Any]], sessions: list[dict[str, Any]], pool: bool) -> list[str]:
    """What is pooled (empty: one protocol, one kind of subject); ReportError when several
    protocols or kinds of subject are there and not ``pool``."""
    kinds = subject_kinds(records)
    if len(kinds) > 1 and not pool:
        raise ReportError(f"the folders hold sessions of {len(kinds)} kinds of subject: "
                          f"{'; '.join(f'{k}: {n} records' for k, n in sorted(kinds.items()))}. Report each on its "
                          "own (one folder per kind), or pass --pool to pool them")
    pooled_kinds = [f"subjects: {k}" for k in sorted(kinds)] if len(kinds) > 1 else []
    protocols = protocols_of(records, sessions)
    variants = sum(max(1, len(v)) for v in protocols.values())
    if variants <= 1:
        return pooled_kinds
    names = [f"{n} (file {h})" if h else n for n, hs in sorted(protocols.items()) for h in (sorted(hs) or [""])]
    if not pool:
        raise ReportError(f"the folders hold sessions of {variants} different protocols: {'; '.join(names)}. Report "
                          "each on its own, or pass --pool to pool them (subjects are then protocol/subject)")
    return names + pooled_kinds


def pooled_labels(sessions: list[dict[str, Any]]) -> dict[str, str]:
    """Session folder → the protocol's label when pooling: its name, plus the file's sha256 prefix
    when one name was run from several files."""
    shas: dict[str, set[str]] = {}
    for s in sessions:
        shas.setdefault(str(s.get("protocol")), set()).add(str(s.get("protocol_sha256") or "")[:8])
    return {s["folder"]: (f"{s.get('protocol')}@{str(s.get('protocol_sha256') or '')[:8]}"
                          if len(shas[str(s.get("protocol"))]) > 1 else str(s.get("protocol"))) for s in sessions}


def tidy_rows(records: list[dict[str, Any]], pooled: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """One row per record; ``pooled`` (session folder → protocol label): subjects become label/subject."""
    rows = []
    for r in records:
        m = r.get("metrics") or {}
        row = {k: r.get(k) for k in ("protocol", "subject", "condition", "task", "block", "index", "repetition",
                                     "practice", "attempt", "status", "world", "policy", "session", "run_dir")}
        row["time_limit_s"] = r.get("time_limit_s")
        for k in ("outcome", "success", "completion_time_s", "duration_s", "path_length_m", "shortest_path_m",
                  "path_efficiency", "collisions", "min_clearance_m", "head_rotation_deg", "head_rotation_deg_per_s"):
            row[k] = m.get(k)
        row["collided_with"] = ";".join(m.get("collided_with", []))
        if pooled is not None:
            row["subject"] = f"{pooled.get(str(r.get('session')), r.get('protocol'))}/{r.get('subject')}"
        d = r.get("display") or {}
        row["phosphenes_shown"] = d.get("phosphenes_shown")
        row["device"] = d.get("device")
        row["own_share"] = d.get("own_share")
        row["fallbacks"] = d.get("fallbacks") or {}
        row["fallback_frames"] = (d.get("frames", 0) - d.get("own_frames", 0)) if "own_share" in d else None
        g = r.get("gaze") or {}            # raspv_experiments.gaze_metrics (trials with eye gaze)
        for k in ("fixations", "mean_fixation_s", "saccades", "mean_saccade_amplitude_deg", "valid_share"):
            row[f"gaze_{k}"] = g.get(k)
        row["factors"] = r.get("factors") or {}
        for k, v in row["factors"].items():
            row[k] = v
        row["trajectory"] = r.get("trajectory")
        row["start"] = r.get("start")
        row["goal"] = r.get("goal")
        rows.append(row)
    rows.sort(key=lambda x: (str(x["protocol"]), str(x["subject"]), x["index"] or 0, x["attempt"] or 0))
    return rows


def write_csv(rows: list[dict[str, Any]], path: Path, factors: list[str] = ()) -> None:
    """The tidy CSV: a column per metric and, for sweeps, per factor (after condition)."""
    columns = COLUMNS[:3] + list(factors) + COLUMNS[3:]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None or (isinstance(r.get(k), float) and math.isnan(r[k])) else r[k])
                        for k in columns})


def analysed(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [r for r in rows if r["status"] == "completed" and not r["practice"]]


def _median_iqr(values: list[float]) -> str:
    v = [x for x in values if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)]
    if not v:
        return "–"
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return f"{med:.2f} [{q1:.2f}–{q3:.2f}]"


def summary_table(rows: list[dict[str, Any]], conditions: list[str]) -> str:
    head = ("<tr><th>condition</th><th>trials</th><th>subjects</th><th>success</th><th>completion time [s]</th>"
            "<th>collisions</th><th>path efficiency</th><th>min. clearance [m]</th><th>head rotation [deg/s]</th></tr>")
    body = []
    for c in conditions:
        t = [r for r in rows if r["condition"] == c]
        ok = sum(1 for r in t if r["success"])
        success = f"{ok}/{len(t)} ({100 * ok / len(t):.0f} %)" if t else "–"
        cells = "".join(f"<td>{_median_iqr([r[k] for r in t])}</td>" for k in
                        ("completion_time_s", "collisions", "path_efficiency", "min_clearance_m", "head_rotation_deg_per_s"))
        body.append(f"<tr><td>{html.escape(c)}</td><td>{len(t)}</td><td>{len({r['subject'] for r in t})}</td>"
                    f"<td>{success}</td>{cells}</tr>")
    return (f"<table class='summary'>{head}{''.join(body)}</table><p class='note'>Cells: median [interquartile "
            "range] over trials; completed, non-practice trials only.</p>")


def gaze_table(rows: list[dict[str, Any]], conditions: list[str]) -> str:
    """Eye-gaze metrics per condition (median [IQR]); empty when no trial logged gaze."""
    if not any(r.get("gaze_fixations") is not None for r in rows):
        return ""
    head = "<tr><th>condition</th><th>trials with gaze</th>" + "".join(
        f"<th>{html.escape(label)}</th>" for _, label in GAZE_MEASURES) + "</tr>"
    body = []
    for c in conditions:
        t = [r for r in rows if r["condition"] == c and r.get("gaze_fixations") is not None]
        cells = "".join(f"<td>{_median_iqr([r[k] for r in t])}</td>" for k, _ in GAZE_MEASURES)
        body.append(f"<tr><td>{html.escape(c)}</td><td>{len(t)}</td>{cells}</tr>")
    return (f"<h2>Eye gaze</h2><table class='gaze'>{head}{''.join(body)}</table><p class='note'>Per trial from its "
            "gaze samples (raspv_experiments/gaze_metrics.py: velocity threshold 30 deg/s, fixations of at least "
            "60 ms; valid share: of the trial's time). Cells: median [interquartile range] over trials.</p>")


def build_report(dirs: list[Path], out: Path, title: str | None = None, pool: bool = False,
                 share_threshold: float = DEFAULT_THRESHOLD) -> Path:
    """Write trials.csv, figures/ and report.html into ``out``; returns the HTML path. Trials
    whose share of frames in their own representation is below ``share_threshold`` are flagged."""
    from raspv_experiments import report_figures as figs
    from raspv_experiments.world_geometry import world_geometry

    records, sessions = find_records(dirs)
    pooled = check_pooling(records, sessions, pool)
    several_protocols = any(not p.startswith("subjects: ") for p in pooled)
    rows = tidy_rows(records, pooled_labels(sessions) if several_protocols else None)
    declared: dict[str, list[str]] = {}
    for s in sessions:
        for k, v in (s.get("factors") or {}).items():
            declared.setdefault(k, list(v))
    factors = sections.factors_of(rows, declared)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(rows, out / "trials.csv", list(factors))
    data = analysed(rows)
    conditions = list(dict.fromkeys(r["condition"] for r in rows))
    tasks = list(dict.fromkeys(r["task"] for r in rows))
    fig_dir = out / "figures"
    figures: list[tuple[str, str]] = []
    figures.append((figs.box_strip(data, conditions, "completion_time_s", "completion time [s]", fig_dir,
                                   "completion_time", "Completion time (filled: reached the goal)"),
                    "Completion time per condition; failed trials at their duration (the time limit)."))
    figures.append((figs.box_strip(data, conditions, "collisions", "collisions per trial", fig_dir, "collisions",
                                   "Collisions per trial"), "Collisions per trial and condition."))
    figures.append((figs.success_rates(data, conditions, fig_dir), "Success rate per condition, 95 % Wilson interval."))
    succeeded = [r for r in data if r["success"]]
    figures.append((figs.box_strip(succeeded, conditions, "path_efficiency",
                                   "path efficiency (shortest / walked)", fig_dir, "path_efficiency",
                                   "Path efficiency of successful trials"),
                    "Planner's shortest path to the goal region / path walked, successful trials."
                    + ("" if succeeded else " Empty: no trial reached the goal, so no path efficiency is defined.")))
    survival_html, curves = sections.survival_section(data, conditions)
    figures.append((figs.kaplan_meier_curves(curves, fig_dir),
                    "Fraction of trials not yet at the goal over time (Kaplan–Meier; trials that ran out of time are "
                    "censored at the limit)."))
    if factors:
        figures.append((figs.main_effects(data, factors, fig_dir),
                        "Success rate at each level of each sweep factor, levels in the sweep's order."))
    for task in tasks:
        world = next((r["world"] for r in rows if r["task"] == task and r.get("world")), None)
        try:
            geometry = world_geometry(world) if world else None
        except Exception:  # noqa: BLE001 - a world that no longer loads still gets its plot
            geometry = None
        figures.append((figs.trajectories(data, conditions, task, fig_dir, geometry),
                        f"Trajectories of task {task} over the world's occupancy map."))
    if max((int(r.get("repetition") or 1) for r in data), default=1) > 1:     # one repetition draws no learning
        figures.append((figs.learning(data, conditions, fig_dir), "Completion time across repetitions."))
    tests = []
    for key, label, proportion in MEASURES:
        values: dict[tuple[str, str], list[float]] = {}
        for r in data:
            v = r.get(key)
            if isinstance(v, bool):
                v = float(v)
            if isinstance(v, (int, float)):
                values.setdefault((r["subject"], r["condition"]), []).append(float(v))
        tests.append(compare_conditions(label, values, conditions, proportion))
    extra = {"warnings": sections.warnings_for(data, conditions, pooled), "virtual": virtual_note(records),
             "subjects": sections.per_subject_table(data, conditions), "survival": survival_html,
             "factors": sections.main_effects_table(data, factors) if factors else "",
             "display": sections.display_section(data, conditions, share_threshold)}
    page = _html(title or ", ".join(sorted({str(r["protocol"]) for r in rows})), rows, data, conditions, figures,
                 tests, sessions, extra)
    path = out / "report.html"
    path.write_text(page, encoding="utf-8")
    return path


def virtual_note(records: list[dict[str, Any]]) -> str:
    """A paragraph saying the subjects were virtual patients ('' when all were people)."""
    policies = sorted({str(r["policy"]) for r in records if r.get("policy")})
    if not policies:
        return ""
    some = " Some" if len(policies) < len(subject_kinds(records)) else " All"
    return (f"<p id='virtual' class='warning'>{some} subjects were <b>virtual patients</b> (scripted policy "
            f"{', '.join(policies)}: simulated walkers that see only the phosphenes, "
            "raspv_experiments/policies.py), not people: these are not human results.</p>")


def _html(title, rows, data, conditions, figures, tests, sessions, extra) -> str:
    statuses: dict[str, int] = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    counts = ", ".join(f"{v} {k}" for k, v in sorted(statuses.items()))
    fig_html = "".join(f"<figure><img src='{html.escape(src)}' alt='{html.escape(cap)}'><figcaption>{html.escape(cap)} "
                       f"<a href='{html.escape(src[:-4])}.pdf'>PDF</a></figcaption></figure>" for src, cap in figures)
    sess_rows = "".join(
        f"<tr><td>{html.escape(str(s.get('subject')))}</td><td>{html.escape(str(s.get('protocol')))}</td>"
        f"<td>{s['trials']}</td><td>{html.escape(str(s.get('subject_kind') or ''))} {html.escape(str(s.get('policy') or ''))}</td>"
        f"<td>{html.escape(str((s.get('software') or {}).get('raspv', '')))} "
        f"{html.escape(str((s.get('software') or {}).get('git_commit', ''))[:10])}</td>"
        f"<td>{html.escape(s['folder'])}</td></tr>" for s in sessions)
    assumptions = "".join(f"<li>{html.escape(a)}</li>" for a in ASSUMPTIONS)
    warn = "".join(f"<p class='warning'>{html.escape(w)}</p>" for w in extra["warnings"])
    factors = f"<h2>Sweep factors (main effects)</h2>{extra['factors']}" if extra["factors"] else ""
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Experiment report: {html.escape(title)}</title>
<style>
body {{ font-family: sans-serif; max-width: 1100px; margin: 2em auto; padding: 0 1em; color: #222; }}
table {{ border-collapse: collapse; margin: 0.5em 0; font-size: 0.9em; }}
td, th {{ border: 1px solid #ccc; padding: 3px 8px; text-align: left; }}
figure {{ display: inline-block; margin: 0.5em; vertical-align: top; max-width: 100%; }}
figure img {{ max-width: 100%; }}
figcaption, .note {{ font-size: 0.85em; color: #555; }}
.warning {{ background: #fff4e0; border-left: 4px solid #e69500; padding: 0.4em 0.8em; }}
</style></head><body>
<h1>Experiment report: {html.escape(title)}</h1>
<p id="counts">{len(rows)} trial records ({counts}) from {len(sessions)} session(s); {len(data)} completed non-practice
trials in {len(conditions)} conditions are analysed. Data: <a href="trials.csv">trials.csv</a> (one row per trial).</p>
{extra["virtual"]}
<div id="warnings">{warn}</div>
<h2>Summary per condition</h2>
{summary_table(data, conditions)}
<div id="gaze">{gaze_table(data, conditions)}</div>
<h2>Per subject</h2>
{extra["subjects"]}
<h2>Figures</h2>
<div id="figures">{fig_html}</div>
<h2>Completion time with the time limit as censoring</h2>
<div id="survival">{extra["survival"]}</div>
<h2>Statistics (repeated measures)</h2>
<ul class="assumptions">{assumptions}</ul>
<div id="stats">{sections.stats_section(tests)}</div>
{factors}
<h2>What the display showed</h2>
<div id="display">{extra["display"]}</div>
<h2>Sessions</h2>
<table><tr><th>subject</th><th>protocol</th><th>records</th><th>subject kind</th><th>software</th><th>folder</th></tr>
{sess_rows}</table>
</body></html>
"""
