"""Figures of an experiment report, with matplotlib (no rclpy): each saved as PNG (for the HTML
page) and PDF (vector, for a paper), sized for one column of a journal page.

Inputs are tidy trial rows (dicts of :func:`raspv_experiments.report.tidy_rows`); only completed,
non-practice trials are drawn.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from raspv_experiments.repeated_measures import wilson_interval  # noqa: E402

plt.rcParams.update({"font.size": 9, "axes.spines.top": False, "axes.spines.right": False,
                     "savefig.bbox": "tight", "figure.dpi": 100})
COLORS = plt.get_cmap("tab10").colors


def _save(fig, out: Path, name: str) -> str:
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / f"{name}.png", dpi=150)
    fig.savefig(out / f"{name}.pdf")
    plt.close(fig)
    return f"{out.name}/{name}.png"


def _by_condition(rows: list[dict[str, Any]], conditions: list[str], key: str) -> list[list[dict[str, Any]]]:
    return [[r for r in rows if r["condition"] == c and _finite(r.get(key))] for c in conditions]


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def box_strip(rows, conditions, key: str, ylabel: str, out: Path, name: str, title: str) -> str:
    """Box plot per condition with every trial as a point (filled: reached the goal)."""
    groups = _by_condition(rows, conditions, key)
    fig, ax = plt.subplots(figsize=(max(3.3, 0.9 * len(conditions) + 1.5), 2.8))
    data = [[g[key] for g in group] for group in groups]
    if any(data):
        ax.boxplot([d if d else [np.nan] for d in data], widths=0.5, showfliers=False,
                   medianprops={"color": "black"}, tick_labels=conditions)
    rng = np.random.default_rng(0)
    for i, group in enumerate(groups, start=1):
        for r in group:
            x = i + rng.uniform(-0.15, 0.15)
            ok = bool(r.get("success"))
            ax.plot(x, r[key], "o", ms=4, mfc=COLORS[0] if ok else "white", mec=COLORS[0], alpha=0.8)
    ax.set_xticks(range(1, len(conditions) + 1), conditions, rotation=20 if len(conditions) > 3 else 0, ha="right"
                  if len(conditions) > 3 else "center")
    ax.set_ylabel(ylabel)
    if key == "collisions":
        ax.set_ylim(bottom=-0.3, top=max([1.0] + [v for d in data for v in d]) + 0.5)
    ax.set_title(title, fontsize=9)
    return _save(fig, out, name)


def success_rates(rows, conditions, out: Path) -> str:
    fig, ax = plt.subplots(figsize=(max(3.3, 0.9 * len(conditions) + 1.5), 2.6))
    for i, c in enumerate(conditions):
        trials = [r for r in rows if r["condition"] == c]
        k = sum(1 for r in trials if r.get("success"))
        n = len(trials)
        rate = k / n if n else math.nan
        lo, hi = wilson_interval(k, n)
        ax.bar(i, rate, color=COLORS[i % 10], width=0.6)
        if n:
            ax.errorbar(i, rate, yerr=[[rate - lo], [hi - rate]], color="black", capsize=3, lw=1)
        ax.text(i, 1.04, f"{k}/{n}", ha="center", fontsize=8)
    ax.set_xticks(range(len(conditions)), conditions, rotation=20 if len(conditions) > 3 else 0,
                  ha="right" if len(conditions) > 3 else "center")
    ax.set_ylim(0, 1.12)
    ax.set_ylabel("success rate (95 % Wilson CI)")
    ax.set_title("Trials that reached the goal", fontsize=9)
    return _save(fig, out, "success_rate")


def learning(rows, conditions, out: Path) -> str:
    """Completion time against repetition: median over subjects per condition, each subject thin."""
    fig, ax = plt.subplots(figsize=(3.6, 2.6))
    for i, c in enumerate(conditions):
        trials = [r for r in rows if r["condition"] == c and _finite(r.get("completion_time_s"))]
        reps = sorted({r["repetition"] for r in trials})
        for s in sorted({r["subject"] for r in trials}):
            pts = sorted((r["repetition"], r["completion_time_s"]) for r in trials if r["subject"] == s)
            if len(pts) > 1:
                ax.plot(*zip(*pts), color=COLORS[i % 10], alpha=0.25, lw=0.8)
        med = [np.median([r["completion_time_s"] for r in trials if r["repetition"] == k]) for k in reps]
        ax.plot(reps, med, "o-", color=COLORS[i % 10], label=c, lw=1.6, ms=4)
    ax.set_xlabel("repetition")
    ax.set_ylabel("completion time [s]")
    if rows:
        ax.set_xticks(sorted({r["repetition"] for r in rows}))
    ax.legend(fontsize=7, frameon=False)
    ax.set_title("Learning across repetitions (median; thin: each subject)", fontsize=9)
    return _save(fig, out, "learning")


def trajectories(rows, conditions, task: str, out: Path, geometry=None) -> str:
    """Every trial's path over the world's map, one panel per condition (green: reached the goal)."""
    trials = [r for r in rows if r["task"] == task and r.get("trajectory")]
    n = max(1, len(conditions))
    cols = min(n, 3)
    nrows = math.ceil(n / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(3.0 * cols, 2.6 * nrows), squeeze=False)
    xs = [v for r in trials for v in r["trajectory"]["x"]] + [r["start"][0] for r in trials] + [r["goal"]["x"] for r in trials]
    ys = [v for r in trials for v in r["trajectory"]["y"]] + [r["start"][1] for r in trials] + [r["goal"]["y"] for r in trials]
    for k, c in enumerate(conditions):
        ax = axes[k // cols][k % cols]
        if geometry is not None:
            g = geometry.grid
            rows_, cols_ = g.shape
            extent = (g.origin[0], g.origin[0] + cols_ * g.resolution, g.origin[1], g.origin[1] + rows_ * g.resolution)
            img = np.where(g.cells == 100, 0.25, np.where(g.cells == 0, 1.0, 0.85))
            ax.imshow(img, origin="lower", extent=extent, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        for r in (r for r in trials if r["condition"] == c):
            t = r["trajectory"]
            color = "tab:green" if r.get("success") else "tab:red"
            ax.plot(t["x"], t["y"], color=color, lw=1.0, alpha=0.8)
            ax.plot(t["x"][-1:], t["y"][-1:], "x", color=color, ms=4)          # where it ended
        first = next((r for r in trials if r["condition"] == c), None) or (trials[0] if trials else None)
        if first is not None:
            ax.plot(first["start"][0], first["start"][1], "k^", ms=5)
            goal = first["goal"]
            ax.add_patch(plt.Circle((goal["x"], goal["y"]), goal["radius"], fill=False, color="tab:blue", lw=1.2))
        if xs and ys:
            pad = 1.5
            ax.set_xlim(min(xs) - pad, max(xs) + pad)
            ax.set_ylim(min(ys) - pad, max(ys) + pad)
        ax.set_aspect("equal")
        ax.set_title(c, fontsize=8)
        ax.tick_params(labelsize=7)
    for k in range(len(conditions), nrows * cols):
        axes[k // cols][k % cols].axis("off")
    fig.suptitle(f"Trajectories, task {task} (x, y in m; ▲ start, ○ goal, × end; green: reached)", fontsize=9)
    return _save(fig, out, f"trajectories-{task}")


def kaplan_meier_curves(curves: dict, out: Path) -> str:
    """Fraction of trials not yet at the goal over time per condition (Kaplan–Meier, censored at
    the time limit; + marks censored trials' ends, shaded: 95 % band)."""
    fig, ax = plt.subplots(figsize=(3.8, 2.8))
    for i, (c, k) in enumerate(curves.items()):
        if not k.n:
            continue
        t = np.concatenate([[0.0], k.times])
        s = np.concatenate([[1.0], k.still_going])
        color = COLORS[i % 10]
        ax.step(t, s, where="post", color=color, lw=1.5, label=f"{c} ({k.events}/{k.n})")
        if len(k.low) == len(k.times) and k.events:
            ax.fill_between(t, np.concatenate([[1.0], k.low]), np.concatenate([[1.0], k.high]), step="post",
                            color=color, alpha=0.12, lw=0)
    ax.set_ylim(-0.02, 1.05)
    ax.set_xlabel("time since the start [s]")
    ax.set_ylabel("not yet at the goal")
    ax.legend(fontsize=7, frameon=False)
    ax.set_title("Completion time, time limit as censoring (Kaplan–Meier)", fontsize=9)
    return _save(fig, out, "kaplan_meier")


def main_effects(rows, factors: dict[str, list[str]], out: Path) -> str:
    """Per sweep factor, the success rate (95 % Wilson) at each level, levels in their order."""
    n = max(1, len(factors))
    fig, axes = plt.subplots(1, n, figsize=(2.6 * n + 0.6, 2.6), squeeze=False, sharey=True)
    for ax, (f, levels) in zip(axes[0], factors.items()):
        rates, lows, highs = [], [], []
        for level in levels:
            t = [r for r in rows if str((r.get("factors") or {}).get(f)) == level]
            k = sum(1 for r in t if r.get("success"))
            rate = k / len(t) if t else math.nan
            lo, hi = wilson_interval(k, len(t))
            rates.append(rate), lows.append(rate - lo if t else 0), highs.append(hi - rate if t else 0)
        x = np.arange(len(levels))
        ax.errorbar(x, rates, yerr=[lows, highs], fmt="o-", color=COLORS[0], capsize=3, lw=1.2, ms=4)
        ax.set_xticks(x, levels, rotation=20 if len(levels) > 3 else 0, ha="right" if len(levels) > 3 else "center")
        ax.set_xlabel(f)
        ax.set_ylim(-0.05, 1.08)
    axes[0][0].set_ylabel("success rate (95 % Wilson CI)")
    fig.suptitle("Main effects of the sweep's factors (each level pooled over the others)", fontsize=9)
    return _save(fig, out, "main_effects")


def level_summaries(summaries, factor: str, out: Path, name: str = "levels", title: str = "") -> str:
    """Success, completion time (limit counted) and collisions per level of an ordered factor —
    means over subjects with their 95 % CIs (:func:`raspv_experiments.quick_sweep.summarise`'s
    rows), levels in their order."""
    x = np.arange(len(summaries))
    fig, axes = plt.subplots(1, 3, figsize=(7.0, 2.3))
    panels = (("reached the goal [%]", lambda s: (100 * s.success, [100 * v for v in s.success_ci])),
              ("time [s] (limit counted)", lambda s: (s.time_s, list(s.time_ci))),
              ("collisions per trial", lambda s: (s.collisions, list(s.collisions_ci))))
    for ax, (label, get) in zip(axes, panels):
        mean = np.array([get(s)[0] for s in summaries])
        ci = np.array([get(s)[1] for s in summaries])
        ax.errorbar(x, mean, yerr=[mean - ci[:, 0], ci[:, 1] - mean], color=COLORS[0], marker="o", capsize=3)
        ax.set_xticks(x, [s.level for s in summaries])
        ax.set_xlabel(factor)
        ax.set_ylabel(label)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, out, name)


def cell_summaries(summaries, cells: dict[str, dict[str, str]], factors: list[str], out: Path, name: str = "cells",
                   title: str = "") -> str:
    """Success, completion time (limit counted) and collisions of every cell of a sweep over
    several factors: the first factor's levels along x, one line per combination of the others
    (``cells``: condition → {factor: level}), means over subjects with their 95 % CIs."""
    first, rest = factors[0], factors[1:]
    levels = list(dict.fromkeys(cells[s.level][first] for s in summaries))
    series: dict[str, list] = {}
    for s in summaries:
        label = ", ".join(f"{f.split('.')[-1]}={cells[s.level][f]}" for f in rest)
        series.setdefault(label, []).append(s)
    fig, axes = plt.subplots(1, 3, figsize=(8.0, 2.6))
    panels = (("reached the goal [%]", lambda s: (100 * s.success, [100 * v for v in s.success_ci])),
              ("time [s] (limit counted)", lambda s: (s.time_s, list(s.time_ci))),
              ("collisions per trial", lambda s: (s.collisions, list(s.collisions_ci))))
    for ax, (label, get) in zip(axes, panels):
        for k, (series_label, rows) in enumerate(series.items()):
            x = np.array([levels.index(cells[s.level][first]) for s in rows]) + 0.06 * (k - (len(series) - 1) / 2)
            mean = np.array([get(s)[0] for s in rows])
            ci = np.array([get(s)[1] for s in rows])
            ax.errorbar(x, mean, yerr=[mean - ci[:, 0], ci[:, 1] - mean], color=COLORS[k % len(COLORS)], marker="o",
                        capsize=3, label=series_label)
        ax.set_xticks(np.arange(len(levels)), levels)
        ax.set_xlabel(first.split(".")[-1])
        ax.set_ylabel(label)
    axes[0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, out, name)
