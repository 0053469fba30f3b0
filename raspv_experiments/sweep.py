"""Sweeps: many scripted-subject sessions of a protocol, headless and in lockstep, in parallel —
worker processes on this machine, or tasks on a Ray cluster, with the same sweep file.

A sweep file (``experiments/*_sweep.yaml``; docs/experiments.md)::

    name: office_modes
    protocol: office_navigation        # the protocol (graph, tasks, design)
    policy: follow_path                # the scripted subject
    subjects: 3                        # virtual subjects 1..3 (or a list of numbers)
    factors:                           # conditions = every combination (replaces the protocol's)
      spv.mode: [grey, chess_wall_obstacles]
      spv.device: [argus_ii, optimist]
    repetitions: 1                     # optional: overrides the protocol's
    graph_overrides: [sim.width:=160]  # optional: graph parameters for the sweep (NODE.PARAM:=VALUE)
    time_limit: 40                     # optional: every task's time limit [s]
    tasks: [corridor]                  # optional: a subset of the protocol's tasks
    subject_params: {max_linear: 0.6}  # optional: parameters of the subject node

One job is one virtual subject's whole session (every condition, so the design stays
repeated-measures); it runs its own graph on its own ROS domain
(:func:`raspv_experiments.domains.private_domain`). Results land as sessions in
``<out>/sessions/<protocol>/<subject>/`` — the same trial records as ``raspv experiment run``,
so ``raspv experiment report <out>`` works on sweeps too; each condition carries its level of every
factor (``Condition.factors``, the records' ``factors``), so the report has a column per factor and
its main effects. Scheduling is the executor's (``concurrent.futures`` or Ray); nothing here
schedules. The driver says how many trials are done over the whole sweep, with the elapsed time
and an ETA (:class:`SweepProgress`); ``domains`` keeps the graphs' ROS domain ids in a range.
Scripted sessions repeat exactly (:mod:`raspv_experiments.session_runner`): the same sweep file
gives the same trial records.
"""
from __future__ import annotations

import concurrent.futures as cf
import io
import itertools
import json
import multiprocessing
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from raspv_bringup.registry import schema_for
from raspv_common.extras import require
from raspv_experiments.design import scripted_subject_id
from raspv_experiments.protocol import Protocol, ProtocolError, parse_protocol, resolve_protocol_path
from raspv_experiments.subject_params import POLICY_NAMES

_KEYS = {"name", "protocol", "policy", "subjects", "factors", "conditions", "tasks", "repetitions", "subject_params",
         "workers", "graph_overrides", "time_limit"}


@dataclass
class Sweep:
    path: Path
    name: str
    protocol: Protocol                     # with the sweep's conditions, tasks and repetitions
    policy: str
    subjects: list[int]
    subject_params: dict[str, Any] = field(default_factory=dict)
    workers: int | None = None


def _factor_label(value: Any) -> str:
    if isinstance(value, list):
        return "+".join(str(v) for v in value) or "none"
    return str(value)


def load_sweep(path: str | Path) -> Sweep:
    """Read and validate a sweep file; ProtocolError with one line per mistake."""
    path = Path(path)
    if not path.is_file():
        raise ProtocolError([f"{path}: no such sweep file"])
    try:
        doc = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ProtocolError([f"{path}: invalid YAML ({getattr(exc, 'problem', None) or exc})"]) from None
    errors: list[str] = []
    if not isinstance(doc, dict):
        raise ProtocolError([f"{path}: expected a mapping with protocol, policy, subjects and factors"])
    for k in sorted(set(doc) - _KEYS, key=str):
        errors.append(f"{path}: {k}: unknown key; allowed: {', '.join(sorted(_KEYS))}")
    ref = doc.get("protocol")
    if not isinstance(ref, str):
        raise ProtocolError(errors + [f"{path}: protocol: expected the name or path of a protocol file"])
    local = path.parent / ref
    ppath = local if local.is_file() else resolve_protocol_path(ref)
    try:
        pdoc = yaml.safe_load(ppath.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ProtocolError(errors + [f"{path}: protocol: cannot read {ppath} ({exc})"]) from None
    if not isinstance(pdoc, dict):
        raise ProtocolError(errors + [f"{ppath}: expected a mapping"])
    policy = doc.get("policy", "follow_path")
    if policy not in POLICY_NAMES:
        errors.append(f"{path}: policy: {policy!r} is not allowed; expected one of {', '.join(POLICY_NAMES)}")
    subjects = doc.get("subjects", 1)
    if isinstance(subjects, int) and not isinstance(subjects, bool) and subjects >= 1:
        subjects = list(range(1, subjects + 1))
    if not (isinstance(subjects, list) and subjects and all(isinstance(s, int) and s >= 1 for s in subjects)):
        errors.append(f"{path}: subjects: expected a count (>= 1) or a list of subject numbers, got {subjects!r}")
        subjects = [1]
    pdoc = dict(pdoc)
    pdoc["name"] = doc.get("name", path.stem)
    factors = doc.get("factors")
    condition_levels: dict[str, dict[str, str]] = {}
    if factors is not None:
        pdoc["conditions"] = _conditions_from_factors(factors, pdoc, path, errors, condition_levels)
    elif "conditions" in doc:
        wanted = doc["conditions"]
        have = pdoc.get("conditions") or {}
        if not (isinstance(wanted, list) and all(w in have for w in wanted)):
            errors.append(f"{path}: conditions: expected a list of the protocol's conditions ({', '.join(have)})")
        else:
            pdoc["conditions"] = {w: have[w] for w in wanted}
    if "tasks" in doc:
        have = pdoc.get("tasks") or {}
        wanted = doc["tasks"]
        if not (isinstance(wanted, list) and all(w in have for w in wanted)):
            errors.append(f"{path}: tasks: expected a list of the protocol's tasks ({', '.join(have)})")
        else:
            pdoc["tasks"] = {w: have[w] for w in wanted}
    if "time_limit" in doc:
        limit = doc["time_limit"]
        if isinstance(limit, bool) or not isinstance(limit, (int, float)) or not limit > 0:
            errors.append(f"{path}: time_limit: expected a positive number of seconds, got {limit!r}")
        else:
            for task in (pdoc.get("tasks") or {}).values():
                if isinstance(task, dict):
                    task["time_limit"] = limit
    if "repetitions" in doc:
        pdoc["design"] = {**(pdoc.get("design") or {}), "repetitions": doc["repetitions"]}
    subject_params = doc.get("subject_params", {}) or {}
    if not isinstance(subject_params, dict):
        errors.append(f"{path}: subject_params: expected a mapping of subject node parameters")
        subject_params = {}
    good, bad = schema_for("subject").validate(subject_params)
    errors += [f"{path}: subject_params.{k}: {m}" for k, m in bad]
    workers = doc.get("workers")
    if workers is not None and not (isinstance(workers, int) and workers >= 1):
        errors.append(f"{path}: workers: expected a number >= 1, got {workers!r}")
        workers = None
    if errors:
        raise ProtocolError(errors)
    if isinstance(pdoc.get("graph"), str):             # the graph file, inlined (the session copy is complete)
        from raspv_bringup.graph import resolve_graph_path

        local_graph = ppath.parent / pdoc["graph"]
        gpath = local_graph if local_graph.is_file() else resolve_graph_path(pdoc["graph"])
        try:
            pdoc["graph"] = yaml.safe_load(gpath.read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise ProtocolError([f"{ppath}: graph: cannot read {gpath} ({exc})"]) from None
    _apply_overrides(pdoc, doc.get("graph_overrides", []), path)
    for task in (pdoc.get("tasks") or {}).values():
        if isinstance(task, dict) and isinstance(task.get("world"), str) and (ppath.parent / task["world"]).is_file():
            task["world"] = str((ppath.parent / task["world"]).resolve())
    text = f"# sweep {path} of protocol {ppath}\n" + yaml.safe_dump(pdoc, sort_keys=False)
    protocol = parse_protocol(pdoc, path, text)
    if isinstance(factors, dict) and factors:       # each condition's level of every factor, for the report
        from dataclasses import replace

        protocol.factors = {str(k): [_factor_label(v) for v in vals] for k, vals in factors.items()}
        protocol.conditions = [replace(c, factors=condition_levels.get(c.name, {})) for c in protocol.conditions]
    return Sweep(path, protocol.name, protocol, policy, subjects, good, workers)


def _apply_overrides(pdoc: dict, overrides: Any, path: Path) -> None:
    """``NODE.PARAM:=VALUE`` entries into the protocol's graph (validated with it)."""
    from raspv_bringup.graph import GraphError, parse_override

    if not isinstance(overrides, list) or not all(isinstance(o, str) for o in overrides):
        raise ProtocolError([f"{path}: graph_overrides: expected a list of NODE.PARAM:=VALUE, e.g. [sim.width:=160]"])
    graph = pdoc.get("graph")
    for text in overrides:
        try:
            node, param, value = parse_override(text)
        except GraphError as exc:
            raise ProtocolError([f"{path}: graph_overrides: {exc.errors[0]}"]) from None
        if not isinstance(graph, dict):
            raise ProtocolError([f"{path}: graph_overrides: the protocol has no graph to override"])
        section = graph.setdefault(node, {"ros__parameters": {}})
        if not isinstance(section, dict):
            raise ProtocolError([f"{path}: graph_overrides: {text}: the graph's {node} section is not a mapping"])
        section.setdefault("ros__parameters", {})[param] = value


def _conditions_from_factors(factors: Any, pdoc: dict, path: Path, errors: list[str],
                             levels: dict[str, dict[str, str]]) -> dict[str, Any]:
    """Every combination of the factors' values as a condition; ``levels`` gets each condition's
    level (label) of every factor."""
    if not isinstance(factors, dict) or not factors:
        errors.append(f"{path}: factors: expected a mapping NODE.PARAM: [values], e.g. spv.mode: [grey, depth]")
        return {}
    axes = []
    for key, values in factors.items():
        if not isinstance(key, str) or "." not in key:
            errors.append(f"{path}: factors.{key}: expected NODE.PARAM (e.g. spv.mode)")
            continue
        if not isinstance(values, list) or not values:
            errors.append(f"{path}: factors.{key}: expected a non-empty list of values")
            continue
        node, param = key.split(".", 1)
        axes.append((node, param, values))
    conditions: dict[str, Any] = {}
    for combo in itertools.product(*[[(n, p, v) for v in vals] for n, p, vals in axes]):
        name = "-".join(f"{p}={_factor_label(v)}" for _, p, v in combo).replace("/", "_").replace(" ", "")
        body: dict[str, dict[str, Any]] = {}
        for n, p, v in combo:
            body.setdefault(n, {})[p] = v
        conditions[name] = body
        levels[name] = {f"{n}.{p}": _factor_label(v) for n, p, v in combo}
    return conditions


# -- running -------------------------------------------------------------------------------------

def run_job(sweep_path: str, number: int, out: str, resume: bool,
            domains: tuple[int, int] | None = None) -> dict[str, Any]:
    """One virtual subject's session on a private ROS domain (in ``domains`` [low, high) when
    given; a worker process or a Ray task). Returns the session's records (so a driver without a
    shared disk still gets them)."""
    from raspv_bringup.middleware import apply_middleware_defaults
    from raspv_experiments.domains import private_domain
    from raspv_experiments.runner_node import RunnerError
    from raspv_experiments.session import SessionError
    from raspv_experiments.session_runner import RunOptions, SessionRunner

    sweep = load_sweep(sweep_path)
    subject = scripted_subject_id(sweep.policy, number)
    with private_domain(*(domains or ())) as domain:
        apply_middleware_defaults()
        options = RunOptions(out=Path(out), subject=subject, policy=sweep.policy, number=number, resume=resume,
                             lockstep=True, headless=True, keys=False, subject_params=dict(sweep.subject_params))
        log = io.StringIO()
        view = _LineView(log)
        runner, error = None, None
        try:
            runner = SessionRunner(sweep.protocol, options, view)
            code = runner.run()
        except (SessionError, RunnerError) as exc:      # a stuck graph, a session that cannot start: one line
            code, error = 1, str(exc)
            view.say(f"stopped: {exc}")
        finally:
            if runner is not None:
                runner.close()
        folder = runner.folder if runner is not None else None
        started = folder is not None and folder.info_path.exists()
        return {"subject": subject, "domain": domain, "code": code, "error": error,
                "session": str(folder.root) if folder is not None else None, "host": os.uname().nodename,
                "session_json": folder.info_path.read_text() if started else None,
                "records": folder.records() if started else [], "log": log.getvalue()}


class _LineView:
    """A view for workers: phase changes and messages as lines in a buffer."""

    def __init__(self, out) -> None:
        self.out = out
        self.last = ""

    def show(self, state) -> None:
        if state.phase != self.last:
            self.out.write(f"{state.done}/{state.total} trial {state.index} {state.label}: {state.phase}\n")
            self.last = state.phase

    def say(self, text: str) -> None:
        self.out.write(text + "\n")


def _store(result: dict[str, Any], out: Path) -> None:
    """Write a job's session where the driver expects it (a Ray node without a shared disk)."""
    if result.get("session_json") is None:          # stopped before its session started
        return
    info = json.loads(result["session_json"])
    folder = out / "sessions" / info["protocol"] / result["subject"]
    if (folder / "trials.jsonl").exists():
        return
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "session.json").write_text(result["session_json"])
    with open(folder / "trials.jsonl", "w") as f:
        for rec in result["records"]:
            f.write(json.dumps(rec) + "\n")


def run_sweep(sweep: Sweep, out: Path, workers: int | None = None, ray_address: str | None = None,
              resume: bool = False, say=print, domains: tuple[int, int] | None = None) -> list[dict[str, Any]]:
    """Run every job of ``sweep``; results (one per subject) in the order they finish. ``domains``
    (low, high): the ROS domain ids the graphs may take (default: any free one in 30–230)."""
    out = Path(out)
    if (out / "sessions").exists() and any((out / "sessions").rglob("session.json")) and not resume:
        raise ProtocolError([f"{out} already holds this sweep's sessions: add --resume to continue them, or use "
                             "another --out"])
    (out / "sessions").mkdir(parents=True, exist_ok=True)
    (out / "sweep.yaml").write_text(sweep.path.read_text())
    (out / "protocol.yaml").write_text(sweep.protocol.text)
    jobs = [(str(sweep.path.resolve()), n, str((out / "sessions").resolve()), resume, domains) for n in sweep.subjects]
    n_cond = len(sweep.protocol.conditions)
    say(f"sweep {sweep.name}: {len(jobs)} virtual subjects × {n_cond} conditions × {len(sweep.protocol.tasks)} tasks × "
        f"{sweep.protocol.design.repetitions} repetitions, policy {sweep.policy}")
    results = []
    if ray_address is not None:
        results = _run_on_ray(jobs, ray_address, say)
    else:
        workers = workers or sweep.workers or max(1, min(len(jobs), (os.cpu_count() or 2) // 2))
        say(f"running on {workers} worker process{'es' if workers > 1 else ''} (each graph on its own ROS domain)")
        ctx = multiprocessing.get_context("spawn")
        progress = SweepProgress(out / "sessions" / sweep.name, _total_trials(sweep), say)
        with cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            pending = {pool.submit(run_job, *job): job for job in jobs}
            while pending:
                done, _ = cf.wait(pending, timeout=PROGRESS_PERIOD_S, return_when=cf.FIRST_COMPLETED)
                for fut in done:
                    results.append(_finished(_result(fut, pending.pop(fut)[1], sweep.policy), say))
                progress.update()
    for r in results:
        _store(r, out)
    return results


PROGRESS_PERIOD_S = 10.0


def _total_trials(sweep: Sweep) -> int:
    from raspv_experiments.design import plan_session

    return sum(len(plan_session(sweep.protocol, scripted_subject_id(sweep.policy, n))) for n in sweep.subjects)


class SweepProgress:
    """Trials done over the whole sweep (counted in the sessions' trials.jsonl on this disk), with
    the elapsed time and an ETA, said whenever the count changes."""

    def __init__(self, sessions: Path, total: int, say) -> None:
        import time

        self.sessions, self.total, self.say = sessions, total, say
        self.started = time.monotonic()
        self.at_start = self.count()
        self.last = self.at_start

    def count(self) -> int:
        from raspv_experiments.session import DONE_STATUSES, read_jsonl

        return sum(1 for f in self.sessions.glob("*/trials.jsonl") for r in read_jsonl(f)
                   if r.get("status") in DONE_STATUSES)

    def update(self) -> None:
        import time

        from raspv_experiments.session_control import elapsed_and_eta

        n = self.count()
        if n != self.last:
            self.last = n
            eta = elapsed_and_eta(n - self.at_start, self.total - self.at_start, time.monotonic() - self.started)
            self.say(f"  {n}/{self.total} trials done, {eta}")


def _result(fut: cf.Future, number: int, policy: str) -> dict[str, Any]:
    """A worker's result, or a failed one when its process died (killed, out of memory)."""
    try:
        return fut.result()
    except cf.BrokenExecutor as exc:
        return {"subject": scripted_subject_id(policy, number), "domain": None, "code": 1, "host": os.uname().nodename,
                "error": f"its worker process ended ({exc})", "session_json": None, "records": [], "log": ""}


def _finished(result: dict[str, Any], say) -> dict[str, Any]:
    done = sum(1 for r in result["records"] if r.get("status") == "completed")
    ok = sum(1 for r in result["records"] if r.get("metrics", {}).get("success"))
    if result.get("error"):
        say(f"  {result['subject']}: stopped after {done} trials: {result['error']}")
    else:
        say(f"  {result['subject']}: {done} trials, {ok} reached the goal (domain {result['domain']} on "
            f"{result['host']})")
    return result


def _run_on_ray(jobs: list[tuple], address: str, say) -> list[dict[str, Any]]:
    ray = require("ray", "raspv experiment sweep --ray")
    if not ray.is_initialized():
        if address in ("", "local"):
            ray.init(num_cpus=max(1, (os.cpu_count() or 2)), include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    resources = ray.cluster_resources()
    say(f"running on Ray ({int(resources.get('CPU', 0))} CPUs in the cluster), one task per virtual subject")
    task = ray.remote(num_cpus=1)(run_job)
    pending = [task.remote(*job) for job in jobs]
    results = []
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        results.append(_finished(ray.get(done[0]), say))
    return results
