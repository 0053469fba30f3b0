"""HTML sections of an experiment report that go beyond the per-condition summary (no rclpy):
warnings a reviewer would raise, the per-subject table, censored completion times (Kaplan–Meier
medians, log-rank tests), effect sizes and bootstrap intervals of the repeated-measures tests,
sweep factors' main effects, and what the wearer saw (the share of frames in each trial's own
representation, :mod:`raspv_common.shown_share`). Inputs are tidy rows of
:func:`raspv_experiments.report.tidy_rows`.
"""
from __future__ import annotations

import html
import math
from typing import Any

import numpy as np

from raspv_experiments.repeated_measures import MeasureTests, holm
from raspv_experiments.survival import kaplan_meier, logrank


def esc(v: Any) -> str:
    return html.escape(str(v))


def fmt(v: Any, digits: int = 2) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if isinstance(v, float):
        return f"{v:.{digits}g}" if abs(v) < 1e-2 or abs(v) >= 1e4 else f"{v:.{digits}f}"
    return esc(v)


def warnings_for(data: list[dict], conditions: list[str], pooled: list[str]) -> list[str]:
    """What a reviewer would point out first: conditions that never reached the goal (a baseline
    that fails everywhere measures nothing), nothing reached at all, pooled protocols."""
    out = []
    protocols = [p for p in pooled if not p.startswith("subjects: ")]
    kinds = [p.removeprefix("subjects: ") for p in pooled if p.startswith("subjects: ")]
    if protocols:
        out.append(f"This report pools {len(protocols)} protocols ({', '.join(protocols)}), as asked (--pool); subjects "
                   "are kept apart per protocol (protocol/subject).")
    if kinds:
        out.append(f"This report pools {len(kinds)} kinds of subject ({', '.join(kinds)}), as asked (--pool): the "
                   "statistics treat them as one population.")
    never = [c for c in conditions if any(r["condition"] == c for r in data)
             and not any(r["condition"] == c and r["success"] for r in data)]
    if data and len(never) == len(conditions):
        out.append("No trial reached the goal in any condition: completion times are all the time limit, path "
                   "efficiency is undefined, and the comparisons below say nothing about performance. Check that "
                   "the task can be done (a virtual patient dry run) before running people.")
    else:
        for c in never:
            n = sum(1 for r in data if r["condition"] == c)
            out.append(f"Condition {c} never reached the goal (0/{n}): as a baseline it fails everywhere, so "
                       "differences from it measure that failure, not how much better the other conditions are.")
    return out


def per_subject_table(data: list[dict], conditions: list[str]) -> str:
    """Subjects × conditions: goals reached / trials, and the median completion time (of all
    trials: failed ones at the time limit)."""
    subjects = sorted({r["subject"] for r in data}, key=str)
    head = "".join(f"<th>{esc(c)}</th>" for c in conditions)
    body = []
    for s in subjects:
        cells = []
        for c in conditions:
            t = [r for r in data if r["subject"] == s and r["condition"] == c]
            if not t:
                cells.append("<td>–</td>")
                continue
            ok = sum(1 for r in t if r["success"])
            times = [r["completion_time_s"] for r in t if isinstance(r.get("completion_time_s"), (int, float))]
            med = f", {np.median(times):.1f} s" if times else ""
            cells.append(f"<td>{ok}/{len(t)}{med}</td>")
        body.append(f"<tr><td>{esc(s)}</td>{''.join(cells)}</tr>")
    return (f"<table class='subjects'><tr><th>subject</th>{head}</tr>{''.join(body)}</table>"
            "<p class='note'>Cells: trials that reached the goal / trials, median completion time (failed trials at "
            "their duration, the time limit).</p>")


def survival_section(data: list[dict], conditions: list[str]) -> tuple[str, dict[str, Any]]:
    """Kaplan–Meier medians per condition and pairwise log-rank tests (Holm): the time limit as
    censoring. Returns the HTML and the curves (for the figure)."""
    groups = {}
    for c in conditions:
        t = [r for r in data if r["condition"] == c and isinstance(r.get("completion_time_s"), (int, float))]
        groups[c] = ([float(r["completion_time_s"]) for r in t], [bool(r["success"]) for r in t])
    curves = {c: kaplan_meier(*groups[c]) for c in conditions}
    rows = "".join(f"<tr><td>{esc(c)}</td><td>{k.n}</td><td>{k.events}</td><td>{k.n - k.events}</td>"
                   f"<td>{fmt(k.median_s, 3) if not math.isnan(k.median_s) else 'not reached'}</td></tr>"
                   for c, k in curves.items())
    parts = ["<table class='survival'><tr><th>condition</th><th>trials</th><th>reached the goal</th>"
             "<th>censored (time limit, aborted)</th><th>Kaplan–Meier median completion time [s]</th></tr>", rows,
             "</table>"]
    tests = [logrank(a, *groups[a], b, *groups[b]) for i, a in enumerate(conditions) for b in conditions[i + 1:]]
    for t, adj in zip(tests, holm([t.p for t in tests])):
        t.p_holm = adj
    if tests:
        parts.append("<table class='logrank'><tr><th>pair</th><th>log-rank z</th><th>p</th><th>p (Holm)</th>"
                     "<th></th></tr>")
        parts += [f"<tr><td>{esc(t.a)} vs {esc(t.b)}</td><td>{fmt(t.statistic, 3)}</td><td>{fmt(t.p, 3)}</td>"
                  f"<td>{fmt(t.p_holm, 3)}</td><td>{esc(t.note)}</td></tr>" for t in tests]
        parts.append("</table>")
    parts.append("<p class='note'>Trials that ran out of time are censored at their duration (scipy.stats.ecdf, "
                 "scipy.stats.logrank). The log-rank test takes trials as independent: with repeated trials per "
                 "subject its p-values are descriptive.</p>")
    return "".join(parts), curves


def effects_table(t: MeasureTests) -> str:
    """The pairwise tests with effect sizes and bootstrap intervals."""
    if not t.pairs:
        return ""
    if t.binary:
        rows = ["<table class='stats'><tr><th>pair</th><th>n</th><th>difference in success [95 % bootstrap CI]</th>"
                "<th>McNemar exact p</th><th>p (Holm)</th><th></th></tr>"]
        for p in t.pairs:
            ci = f" [{fmt(p.ci_low, 2)}, {fmt(p.ci_high, 2)}]" if not math.isnan(p.ci_low) else ""
            rows.append(f"<tr><td>{esc(p.a)} − {esc(p.b)}</td><td>{p.n}</td><td>{fmt(p.median_difference, 2)}{ci}</td>"
                        f"<td>{fmt(p.p, 3)}</td><td>{fmt(p.p_holm, 3)}</td><td>{esc(p.note)}</td></tr>")
        return "".join(rows) + "</table>"
    rows = ["<table class='stats'><tr><th>pair</th><th>n</th><th>median difference [95 % bootstrap CI]</th>"
            "<th>rank-biserial r</th><th>W</th><th>p</th><th>p (Holm)</th><th></th></tr>"]
    for p in t.pairs:
        ci = f" [{fmt(p.ci_low, 3)}, {fmt(p.ci_high, 3)}]" if not math.isnan(p.ci_low) else ""
        rows.append(f"<tr><td>{esc(p.a)} − {esc(p.b)}</td><td>{p.n}</td><td>{fmt(p.median_difference, 3)}{ci}</td>"
                    f"<td>{fmt(p.rank_biserial, 2)}</td><td>{fmt(p.statistic, 3)}</td><td>{fmt(p.p, 3)}</td>"
                    f"<td>{fmt(p.p_holm, 3)}</td><td>{esc(p.note)}</td></tr>")
    rows.append("</table>")
    return "".join(rows)


def stats_section(tests: list[MeasureTests]) -> str:
    parts = []
    for t in tests:
        parts.append(f"<h3>{esc(t.measure)}</h3>")
        n = len(t.subjects)
        parts.append(f"<p>{n} subject{'' if n == 1 else 's'} with every condition.")
        if t.binary and not math.isnan(t.friedman_p):
            parts.append(f" Cochran's Q({len(t.conditions) - 1}) = {t.friedman_statistic:.2f}, p = {t.friedman_p:.3g}.")
        elif t.binary and t.friedman_note:
            parts.append(f" Cochran's Q: {esc(t.friedman_note)}.")
        elif not math.isnan(t.friedman_p):
            parts.append(f" Friedman χ²({len(t.conditions) - 1}) = {t.friedman_statistic:.2f}, p = {t.friedman_p:.3g}, "
                         f"Kendall's W = {t.kendall_w:.2f}.")
        elif t.friedman_note:
            parts.append(f" Friedman: {esc(t.friedman_note)}.")
        parts.append("</p>")
        parts.append(effects_table(t))
        if t.note:
            parts.append(f"<p class='note'>{esc(t.note)}</p>")
    return "".join(parts)


def factors_of(rows: list[dict], declared: dict[str, list[str]]) -> dict[str, list[str]]:
    """Factor → its levels in order: as the sweep file lists them (session.json), else numeric
    order when every level is a number, else order of appearance."""
    out: dict[str, list[str]] = {}
    for r in rows:
        for k, v in (r.get("factors") or {}).items():
            out.setdefault(k, [])
            if str(v) not in out[k]:
                out[k].append(str(v))
    for k, levels in out.items():
        order = declared.get(k)
        if order:
            out[k] = [v for v in order if v in levels] + [v for v in levels if v not in order]
        else:
            try:
                out[k] = sorted(levels, key=float)
            except ValueError:
                pass
    return out


def main_effects_table(data: list[dict], factors: dict[str, list[str]]) -> str:
    """Per factor and level (in order): trials, success, median completion time — each level
    pooled over the other factors' levels (a main effect)."""
    parts = []
    for f, levels in factors.items():
        parts.append(f"<h3>{esc(f)}</h3><table class='main-effect'><tr><th>level</th><th>trials</th><th>success</th>"
                     "<th>Kaplan–Meier median completion time [s]</th></tr>")
        for level in levels:
            t = [r for r in data if str((r.get("factors") or {}).get(f)) == level]
            ok = sum(1 for r in t if r["success"])
            km = kaplan_meier([float(r["completion_time_s"]) for r in t
                               if isinstance(r.get("completion_time_s"), (int, float))],
                              [bool(r["success"]) for r in t if isinstance(r.get("completion_time_s"), (int, float))])
            med = "not reached" if math.isnan(km.median_s) else f"{km.median_s:.1f}"
            parts.append(f"<tr><td>{esc(level)}</td><td>{len(t)}</td><td>{ok}/{len(t)}"
                         f"{f' ({100 * ok / len(t):.0f} %)' if t else ''}</td><td>{med}</td></tr>")
        parts.append("</table>")
    return "".join(parts)


def display_section(data: list[dict], conditions: list[str], threshold: float) -> str:
    """What the wearer saw: per condition the share of frames in the condition's own mode and
    overlays, and every trial below ``threshold`` with the fallbacks shown instead."""
    with_share = [r for r in data if isinstance(r.get("own_share"), (int, float))]
    if not with_share:
        return "<p class='note'>These records do not say what the display showed (recorded from issue 21 on).</p>"
    rows = []
    for c in conditions:
        t = [r for r in with_share if r["condition"] == c]
        if not t:
            continue
        shares = [r["own_share"] for r in t]
        flagged = sum(1 for s in shares if s < threshold)
        rows.append(f"<tr><td>{esc(c)}</td><td>{len(t)}</td><td>{100 * min(shares):.2f} %</td>"
                    f"<td>{100 * float(np.median(shares)):.2f} %</td><td>{flagged}</td></tr>")
    parts = [f"<table class='display'><tr><th>condition</th><th>trials</th><th>lowest share</th><th>median share</th>"
             f"<th>trials below {100 * threshold:g} %</th></tr>{''.join(rows)}</table>"]
    low = [r for r in with_share if r["own_share"] < threshold]
    if low:
        parts.append("<p class='warning'>These trials showed something else than their condition's representation "
                     f"for more than {100 * (1 - threshold):g} % of their frames (stale inputs: a fallback mode, the "
                     "no-data ring, a dropped overlay); consider excluding or repeating them:</p><table class='flagged'>"
                     "<tr><th>subject</th><th>trial</th><th>condition</th><th>share</th><th>shown instead</th></tr>")
        for r in low:
            instead = ", ".join(f"{k} {v.get('frames', 0)} frames / {v.get('seconds', 0):.2f} s"
                                for k, v in (r.get("fallbacks") or {}).items())
            parts.append(f"<tr><td>{esc(r['subject'])}</td><td>{esc(r['index'])}</td><td>{esc(r['condition'])}</td>"
                         f"<td>{100 * r['own_share']:.2f} %</td><td>{esc(instead)}</td></tr>")
        parts.append("</table>")
    else:
        parts.append(f"<p class='note'>Every trial showed its own representation on at least {100 * threshold:g} % of "
                     "its frames.</p>")
    return "".join(parts)
