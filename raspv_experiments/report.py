"""``raspv experiment report DIR...``: sessions and sweeps → a tidy CSV and an HTML report (no rclpy).

Every ``trials.jsonl`` under the given folders is read (sessions of ``raspv experiment run``
and of sweeps alike). Out come, in ``-o OUT``:

- ``trials.csv``   one row per trial record (tidy: one observation per row, one variable per
                   column; ``status`` says completed/skipped/repeated/interrupted, ``practice``
                   marks practice trials — the figures and tests use completed non-practice ones);
- ``report.html``  per-condition summary, figures (``figures/*.png`` and ``*.pdf``), repeated-
                   measures statistics with their assumptions (:mod:`raspv_experiments.repeated_measures`),
                   and where the data came from (sessions, software versions).
"""
from __future__ import annotations

import csv
import html
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from raspv_experiments.repeated_measures import ASSUMPTIONS, MeasureTests, compare_conditions
from raspv_experiments.session import read_jsonl

COLUMNS = ["protocol", "subject", "condition", "task", "block", "index", "repetition", "practice", "attempt", "status",
           "outcome", "success", "completion_time_s", "duration_s", "time_limit_s", "path_length_m", "shortest_path_m",
           "path_efficiency", "collisions", "collided_with", "min_clearance_m", "head_rotation_deg",
           "head_rotation_deg_per_s", "world", "policy", "session", "run_dir"]
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
                             ("protocol", "subject", "subject_kind", "policy", "created", "software", "protocol_sha256")}})
    if not records:
        raise ReportError(f"no trial records (trials.jsonl) under {', '.join(map(str, dirs))}")
    return records, sessions


def tidy_rows(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
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
        row["trajectory"] = r.get("trajectory")
        row["start"] = r.get("start")
        row["goal"] = r.get("goal")
        rows.append(row)
    rows.sort(key=lambda x: (str(x["protocol"]), str(x["subject"]), x["index"] or 0, x["attempt"] or 0))
    return rows


def write_csv(rows: list[dict[str, Any]], path: Path) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None or (isinstance(r.get(k), float) and math.isnan(r[k])) else r[k])
                        for k in COLUMNS})


def analysed(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [r for r in rows if r["status"] == "completed" and not r["practice"]]


def _fmt(v: Any, digits: int = 2) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if isinstance(v, float):
        return f"{v:.{digits}g}" if abs(v) < 1e-2 or abs(v) >= 1e4 else f"{v:.{digits}f}"
    return html.escape(str(v))


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


def stats_section(tests: list[MeasureTests]) -> str:
    parts = []
    for t in tests:
        parts.append(f"<h3>{html.escape(t.measure)}</h3>")
        n = len(t.subjects)
        parts.append(f"<p>{n} subject{'' if n == 1 else 's'} with every condition.")
        if not math.isnan(t.friedman_p):
            parts.append(f" Friedman χ²({len(t.conditions) - 1}) = {t.friedman_statistic:.2f}, p = {t.friedman_p:.3g}.")
        elif t.friedman_note:
            parts.append(f" Friedman: {html.escape(t.friedman_note)}.")
        parts.append("</p>")
        if t.pairs:
            parts.append("<table class='stats'><tr><th>pair</th><th>n</th><th>median difference</th><th>W</th>"
                         "<th>p</th><th>p (Holm)</th><th></th></tr>")
            for p in t.pairs:
                parts.append(f"<tr><td>{html.escape(p.a)} − {html.escape(p.b)}</td><td>{p.n}</td>"
                             f"<td>{_fmt(p.median_difference, 3)}</td><td>{_fmt(p.statistic, 3)}</td>"
                             f"<td>{_fmt(p.p, 3)}</td><td>{_fmt(p.p_holm, 3)}</td><td>{html.escape(p.note)}</td></tr>")
            parts.append("</table>")
        if t.note:
            parts.append(f"<p class='note'>{html.escape(t.note)}</p>")
    return "".join(parts)


def build_report(dirs: list[Path], out: Path, title: str | None = None) -> Path:
    """Write trials.csv, figures/ and report.html into ``out``; returns the HTML path."""
    from raspv_experiments import report_figures as figs
    from raspv_experiments.world_geometry import world_geometry

    records, sessions = find_records(dirs)
    rows = tidy_rows(records)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(rows, out / "trials.csv")
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
    figures.append((figs.box_strip([r for r in data if r["success"]], conditions, "path_efficiency",
                                   "path efficiency (shortest / walked)", fig_dir, "path_efficiency",
                                   "Path efficiency of successful trials"),
                    "Planner's shortest path to the goal region / path walked, successful trials."))
    for task in tasks:
        world = next((r["world"] for r in rows if r["task"] == task and r.get("world")), None)
        try:
            geometry = world_geometry(world) if world else None
        except Exception:  # noqa: BLE001 - a world that no longer loads still gets its plot
            geometry = None
        figures.append((figs.trajectories(data, conditions, task, fig_dir, geometry),
                        f"Trajectories of task {task} over the world's occupancy map."))
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
    page = _html(title or ", ".join(sorted({str(r["protocol"]) for r in rows})), rows, data, conditions, figures,
                 tests, sessions)
    path = out / "report.html"
    path.write_text(page, encoding="utf-8")
    return path


def _html(title, rows, data, conditions, figures, tests, sessions) -> str:
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
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>Experiment report: {html.escape(title)}</title>
<style>
body {{ font-family: sans-serif; max-width: 1100px; margin: 2em auto; padding: 0 1em; color: #222; }}
table {{ border-collapse: collapse; margin: 0.5em 0; font-size: 0.9em; }}
td, th {{ border: 1px solid #ccc; padding: 3px 8px; text-align: left; }}
figure {{ display: inline-block; margin: 0.5em; vertical-align: top; max-width: 100%; }}
figure img {{ max-width: 100%; }}
figcaption, .note {{ font-size: 0.85em; color: #555; }}
</style></head><body>
<h1>Experiment report: {html.escape(title)}</h1>
<p id="counts">{len(rows)} trial records ({counts}) from {len(sessions)} session(s); {len(data)} completed non-practice
trials in {len(conditions)} conditions are analysed. Data: <a href="trials.csv">trials.csv</a> (one row per trial).</p>
<h2>Summary per condition</h2>
{summary_table(data, conditions)}
<h2>Figures</h2>
<div id="figures">{fig_html}</div>
<h2>Statistics (repeated measures)</h2>
<ul class="assumptions">{assumptions}</ul>
<div id="stats">{stats_section(tests)}</div>
<h2>Sessions</h2>
<table><tr><th>subject</th><th>protocol</th><th>records</th><th>subject kind</th><th>software</th><th>folder</th></tr>
{sess_rows}</table>
</body></html>
"""
