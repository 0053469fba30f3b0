"""A sweep file run in one process with :func:`~raspv_experiments.quick_trial.quick_trial` (no
rclpy, no graph): every virtual subject × condition × task × repetition of the sweep, walked by
the same cores a session runs (simulator, phosphene simulator, the policy), in seconds per trial
instead of the lockstep graph's minutes — for sweeps with many trials on a small machine
(``raspv experiment quick-sweep SWEEP``). The records are not a session's (no trial logs, no
display record) but one CSV row per trial; the summary gives, per level of the sweep's factor
(per cell — each combination of levels — when it has several), success, collisions and
completion time with bootstrap 95 % confidence intervals over subjects (seeded, so the same
sweep gives the same table).

Only conditions the phosphene simulator renders alone are run here: modes that need the scene
node (Chess-Floor, Wall-Obstacles, …) run in sessions (``raspv experiment sweep``).

Each virtual subject N has its ability (:func:`~raspv_experiments.subject_ability.subject_ability`)
and the sweep's ``subject_params``; each trial is seeded as in N's session
(:func:`~raspv_experiments.design.trial_seed` of its position in
:func:`~raspv_experiments.design.plan_session`: the design's counterbalanced or random order,
practice trials counted though not run here), so a quick sweep and a graph sweep of the same
sweep file walk the same trials for every subject. Rows come in the sweep's order (subject, then
its conditions), not the session's.
"""
from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Callable

import numpy as np

from raspv_experiments.sweep import Sweep

QUICK_INPUTS = frozenset({"color", "depth", "camera", "camera_pose"})    # what quick_trial renders
SCENE_MODES_HINT = "run it with `raspv experiment sweep` (it needs the scene node)"
COLUMNS = ("subject", "condition", "factors", "task", "repetition", "success", "completion_time_s", "duration_s",
           "collisions", "path_length_m", "phosphenes_shown", "wall_s")


@dataclass
class QuickTrialRecord:
    subject: int
    condition: str
    factors: dict[str, str]
    task: str
    repetition: int
    success: bool
    completion_time_s: float          # NaN when the goal was not reached
    duration_s: float                 # sim time walked [s]
    collisions: int
    path_length_m: float
    phosphenes_shown: int
    wall_s: float                     # wall-clock time the trial took [s]

    def row(self) -> dict[str, Any]:
        r = {f.name: getattr(self, f.name) for f in fields(self)}
        r["factors"] = ";".join(f"{k}={v}" for k, v in self.factors.items())
        return r


def _graph_params(sweep: Sweep, node: str) -> dict[str, Any]:
    try:
        return dict(sweep.protocol.graph.node(node).params)
    except StopIteration:
        return {}


def subject_config(sweep: Sweep, subject: int, seed: int):
    """The policy configuration of virtual subject ``subject`` (its ability, the sweep's
    ``subject_params``), seeded ``seed``."""
    from raspv_bringup.registry import schema_for
    from raspv_experiments.policies import PolicyConfig
    from raspv_experiments.subject_ability import subject_ability

    p = {**schema_for("subject").defaults(), **subject_ability(subject), **sweep.subject_params, "seed": seed}
    names = {f.name for f in fields(PolicyConfig)}
    return PolicyConfig(**{k: v for k, v in p.items() if k in names})


def check_quick(sweep: Sweep) -> list[str]:
    """Why this sweep cannot run in one process (empty: it can)."""
    from raspv_spv.modes import mode_class

    problems = []
    base = _graph_params(sweep, "spv")
    for c in sweep.protocol.conditions:
        mode = c.params.get("spv", {}).get("mode", base.get("mode", "depth"))
        if mode == "learned" or not mode_class(mode).needs <= QUICK_INPUTS:
            problems.append(f"{sweep.path}: condition {c.name}: mode {mode!r} needs the scene node; {SCENE_MODES_HINT}")
        other = sorted(set(c.params) - {"spv"})
        if other:
            problems.append(f"{sweep.path}: condition {c.name}: sets {', '.join(other)} parameters; "
                            f"quick sweeps vary only spv parameters; {SCENE_MODES_HINT}")
    if sweep.policy == "learned":
        from raspv_experiments.learned_policy import representation_mismatch

        for c in sweep.protocol.conditions:
            mismatch = representation_mismatch(sweep.subject_params.get("model", ""), {**base, **c.params.get("spv", {})})
            if mismatch:
                problems.append(f"{sweep.path}: condition {c.name}: {mismatch.split(': refused')[0]}: refused "
                                "(a quick sweep runs a learned patient only on its training representation)")
                break
    return problems


def session_seeds(sweep: Sweep) -> dict[tuple[int, str, str, int], int]:
    """The seed of every trial (subject, condition, task, repetition) of ``sweep`` as the subject's
    session seeds it: from the trial's position in the session's plan."""
    from raspv_experiments.design import plan_session, scripted_subject_id, trial_seed

    return {(s, t.condition, t.task, t.repetition): trial_seed(s, t.index) for s in sweep.subjects
            for t in plan_session(sweep.protocol, scripted_subject_id(sweep.policy, s)) if not t.practice}


def run_quick_sweep(sweep: Sweep, out_csv: str | Path | None = None,
                    progress: Callable[[str], None] | None = print,
                    only: set[tuple[int, str, str, int]] | None = None, workers: int = 1) -> list[QuickTrialRecord]:
    """Every trial of ``sweep`` with :func:`quick_trial`, in order (subject, then its conditions);
    each row appended to ``out_csv`` (flushed) as the trial ends. ``only``: just these trials
    (subject, condition, task, repetition), each seeded as in the whole sweep (a sample re-run).
    ``workers`` > 1: the trials run on that many worker processes (spawned; each trial is seeded
    on its own, so the records are the same), rows written and returned in the same order."""
    problems = check_quick(sweep)
    if problems:
        raise ValueError("\n".join(problems))
    plan = [(s, c.name, t.name, r) for s in sweep.subjects for c in sweep.protocol.conditions
            for t in sweep.protocol.tasks for r in range(1, sweep.protocol.design.repetitions + 1)]
    seeds = session_seeds(sweep)
    if only is not None:
        missing = sorted(set(only) - set(seeds))
        if missing:
            raise ValueError(f"{sweep.path}: no such trials in the sweep: {missing}")
        plan = [k for k in plan if k in only]
    records: list[QuickTrialRecord] = []
    writer, handle = None, None
    if out_csv is not None:
        Path(out_csv).parent.mkdir(parents=True, exist_ok=True)
        handle = open(out_csv, "w", newline="")
        writer = csv.DictWriter(handle, fieldnames=COLUMNS)
        writer.writeheader()
    started = time.monotonic()

    def done(rec: QuickTrialRecord) -> None:
        records.append(rec)
        if writer is not None:
            writer.writerow(rec.row())
            handle.flush()
        if progress is not None:
            i, elapsed = len(records), time.monotonic() - started
            eta = elapsed / i * (len(plan) - i)
            progress(f"[{i}/{len(plan)}] S{rec.subject:02d} {rec.condition} {rec.task} r{rec.repetition}: "
                     f"{'goal' if rec.success else 'time limit'} {rec.duration_s:.1f} s, {rec.collisions} collisions "
                     f"({rec.wall_s:.0f} s; elapsed {elapsed / 60:.1f} min, ETA {eta / 60:.1f} min)")
    try:
        if workers > 1 and len(plan) > 1:
            import concurrent.futures as cf
            import multiprocessing

            with cf.ProcessPoolExecutor(max_workers=min(workers, len(plan)),
                                        mp_context=multiprocessing.get_context("spawn")) as pool:
                for rec in pool.map(run_quick_trial, [sweep] * len(plan), plan, [seeds[k] for k in plan]):
                    done(rec)                                # in the plan's order
        else:
            for key in plan:
                done(run_quick_trial(sweep, key, seeds[key]))
    finally:
        if handle is not None:
            handle.close()
    return records


def run_quick_trial(sweep: Sweep, key: tuple[int, str, str, int], seed: int) -> QuickTrialRecord:
    """One trial of ``sweep`` (subject, condition, task, repetition) with its session ``seed``."""
    from raspv_experiments.quick_trial import quick_trial

    subject, cond_name, task_name, rep = key
    cond = next(c for c in sweep.protocol.conditions if c.name == cond_name)
    task = next(t for t in sweep.protocol.tasks if t.name == task_name)
    sim = _graph_params(sweep, "sim")
    spv = {**_graph_params(sweep, "spv"), **cond.params.get("spv", {}), "headless": True}
    t0 = time.monotonic()
    res = quick_trial(task.world, (task.start_x, task.start_y, math.radians(task.start_yaw_deg)),
                      (task.goal.x, task.goal.y, task.goal.radius), task.time_limit, spv=spv,
                      policy=sweep.policy, config=subject_config(sweep, subject, seed),
                      rate=float(sim.get("rate", 10.0)), size=(int(sim.get("width", 160)), int(sim.get("height", 120))),
                      goal_knowledge=sweep.protocol.goal_knowledge, sim_params=sim,
                      policy_kw={"model": sweep.subject_params["model"]}
                      if sweep.policy == "learned" and sweep.subject_params.get("model") else None)
    length = float(np.hypot(*np.diff(np.asarray(res.path), axis=0).T).sum()) if len(res.path) > 1 else 0.0
    return QuickTrialRecord(subject, cond.name, dict(cond.factors), task.name, rep, res.success,
                            res.time_s if res.success else math.nan, res.time_s, res.collisions, length,
                            res.phosphenes, time.monotonic() - t0)


@dataclass
class LevelSummary:
    level: str
    subjects: int
    success: float                        # fraction of trials reaching the goal
    success_ci: tuple[float, float]       # bootstrap 95 % CI over subjects
    collisions: float                     # mean per trial
    collisions_ci: tuple[float, float]
    time_s: float                         # mean completion time, the time limit for trials that did not finish
    time_ci: tuple[float, float]
    phosphenes_shown: int


def read_quick_csv(paths: list[str | Path]) -> list[QuickTrialRecord]:
    """The rows of quick-sweep CSV files (e.g. one per process of a sweep split by ``--subjects``),
    in file order; a trial present twice (same subject, condition, task, repetition) is an error."""
    out: list[QuickTrialRecord] = []
    seen: set[tuple] = set()
    for path in paths:
        with open(path, newline="") as handle:
            reader = csv.DictReader(handle)
            if reader.fieldnames is None or set(reader.fieldnames) != set(COLUMNS):
                raise ValueError(f"{path}: not a quick-sweep CSV (expected the columns {', '.join(COLUMNS)})")
            for line, row in enumerate(reader, 2):
                try:
                    factors = dict(kv.split("=", 1) for kv in row["factors"].split(";") if kv)
                    rec = QuickTrialRecord(int(row["subject"]), row["condition"], factors, row["task"],
                                           int(row["repetition"]), row["success"] == "True",
                                           float(row["completion_time_s"]), float(row["duration_s"]),
                                           int(row["collisions"]), float(row["path_length_m"]),
                                           int(row["phosphenes_shown"]), float(row["wall_s"]))
                except (ValueError, TypeError) as exc:
                    raise ValueError(f"{path}:{line}: {exc}") from None
                key = (rec.subject, rec.condition, rec.task, rec.repetition)
                if key in seen:
                    raise ValueError(f"{path}:{line}: trial {key} appears twice")
                seen.add(key)
                out.append(rec)
    return out


def measure_of(record: QuickTrialRecord, measure: str, time_limits: dict[str, float]) -> float:
    """One trial's ``success`` (0/1), ``collisions`` or ``time_s`` (completion time; a trial cut
    off counted at its task's time limit, a lower bound)."""
    if measure == "success":
        return float(record.success)
    if measure == "collisions":
        return float(record.collisions)
    if measure == "time_s":
        return record.completion_time_s if record.success else time_limits.get(record.task, record.duration_s)
    raise ValueError(f"unknown measure {measure!r}: success, collisions or time_s")


def bootstrap_mean_ci(values: np.ndarray, seed: int = 1) -> tuple[float, float]:
    """Percentile-bootstrap 95 % CI of the mean of ``values`` (9999 resamples, seeded); a point
    when there are fewer than 2 values or all are equal."""
    from scipy import stats

    v = np.asarray(values, float)
    if len(v) < 2 or np.all(v == v[0]):
        return float(v.mean()), float(v.mean())
    ci = stats.bootstrap((v,), np.mean, confidence_level=0.95, n_resamples=9999, method="percentile",
                         random_state=np.random.default_rng(seed)).confidence_interval
    return float(ci.low), float(ci.high)


def summarise(records: list[QuickTrialRecord], time_limits: dict[str, float], factor: str | None = None,
              levels: list[str] | None = None) -> list[LevelSummary]:
    """Per level of ``factor`` (or per condition): each subject's mean over its trials, then the
    mean over subjects with a percentile bootstrap 95 % CI over subjects (9999 resamples, seeded).
    Completion time counts a trial cut off at the time limit as the limit (a lower bound)."""
    key = (lambda r: r.factors.get(factor, r.condition)) if factor else (lambda r: r.condition)
    order = levels or list(dict.fromkeys(key(r) for r in records))
    out = []
    for level in order:
        rows = [r for r in records if key(r) == level]
        if not rows:
            continue
        subjects = sorted({r.subject for r in rows})
        per = {name: np.array([np.mean([measure_of(r, name, time_limits) for r in rows if r.subject == s])
                               for s in subjects]) for name in ("success", "collisions", "time_s")}
        out.append(LevelSummary(level, len(subjects), float(per["success"].mean()), bootstrap_mean_ci(per["success"]),
                                float(per["collisions"].mean()), bootstrap_mean_ci(per["collisions"]),
                                float(per["time_s"].mean()), bootstrap_mean_ci(per["time_s"]),
                                int(np.median([r.phosphenes_shown for r in rows]))))
    return out


def summary_table(summaries: list[LevelSummary], factor: str,
                  cells: dict[str, dict[str, str]] | None = None) -> str:
    """A Markdown table of :func:`summarise`'s rows; with ``cells`` (condition → {factor: level},
    the rows summarised per condition of a sweep over several factors) a column per factor."""
    names = list(next(iter(cells.values()))) if cells else [factor]
    lines = [f"| {' | '.join(names)} | shown | subjects | success [95 % CI] | collisions/trial [95 % CI] | "
             "time s [95 % CI] |", "|---" * len(names) + "|---|---|---|---|---|"]
    for s in summaries:
        first = " | ".join(str(cells[s.level].get(n, "")) for n in names) if cells else s.level
        lines.append(f"| {first} | {s.phosphenes_shown} | {s.subjects} | {100 * s.success:.0f} % "
                     f"[{100 * s.success_ci[0]:.0f}, {100 * s.success_ci[1]:.0f}] | {s.collisions:.2f} "
                     f"[{s.collisions_ci[0]:.2f}, {s.collisions_ci[1]:.2f}] | {s.time_s:.1f} "
                     f"[{s.time_ci[0]:.1f}, {s.time_ci[1]:.1f}] |")
    return "\n".join(lines)


def stratified_sample(records: list[QuickTrialRecord], seed: int = 33, by_task: bool = True,
                      max_wall_s: float | None = None) -> set[tuple[int, str, str, int]]:
    """One trial of every (condition, task) cell of ``records`` (of every condition, tasks pooled,
    when not ``by_task``), each from another subject where there are enough (drawn seeded: the same
    records give the same sample) — rows to re-run and compare, so a documented table is checked in
    every condition, not in one subject's session. ``max_wall_s``: drawn among the rows that took at
    most that long when recorded (a cheap sample; a cell with none keeps all its rows)."""
    rng = np.random.default_rng(seed)
    cells: dict[tuple[str, str], list[QuickTrialRecord]] = {}
    for r in records:
        cells.setdefault((r.condition, r.task if by_task else ""), []).append(r)
    if max_wall_s is not None:
        cells = {k: [r for r in rows if r.wall_s <= max_wall_s] or rows for k, rows in cells.items()}
    used: set[int] = set()
    out = set()
    for key in sorted(cells):
        rows = sorted(cells[key], key=lambda r: (r.subject, r.repetition))
        fresh = [r for r in rows if r.subject not in used] or rows
        pick = fresh[int(rng.integers(len(fresh)))]
        used.add(pick.subject)
        out.add((pick.subject, pick.condition, pick.task, pick.repetition))
    return out
