"""``raspv experiment check|plan|run|sweep|report`` — protocols, sessions, sweeps and reports.

    raspv experiment check PROTOCOL...                    validate protocol (or sweep) files
    raspv experiment plan PROTOCOL --subject S07          the subject's trial order
    raspv experiment run PROTOCOL --subject S07 [--resume] [--bag] [--out DIR]
    raspv experiment run PROTOCOL --subject scripted:follow_path[:N]
    raspv experiment sweep SWEEP [--workers N | --ray [ADDRESS]] [--out DIR] [--resume]
    raspv experiment quick-sweep SWEEP [--out CSV] [--subjects 1,2,...]   (one process, the cores; no graph)
    raspv experiment report DIR... [-o OUT]

PROTOCOL is a path or the name of a file in ``experiments/``. docs/experiments.md is the guide.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

ACTIONS = ("check", "plan", "run", "sweep", "quick-sweep", "report")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    p = sub.add_parser("check", help="validate protocol or sweep files (one line per mistake)")
    p.add_argument("files", nargs="+", metavar="FILE")
    p = sub.add_parser("plan", help="print a subject's trial order")
    p.add_argument("protocol")
    p.add_argument("--subject", required=True, help="subject id with a number, e.g. S07, or scripted:POLICY[:N]")
    p = sub.add_parser("run", help="run a session: the graph, then every trial of the protocol for one subject")
    p.add_argument("protocol")
    p.add_argument("--subject", required=True, help="S07 (a person), or scripted[:POLICY[:N]] (a virtual subject: "
                                                    "navigate (the default), follow_path, wander_avoid or learned, number N)")
    p.add_argument("--out", default="sessions", help="sessions go to OUT/<protocol>/<subject>/ (default: sessions)")
    p.add_argument("--resume", action="store_true", help="continue an interrupted session at its next trial")
    p.add_argument("--bag", action="store_true", default=None, help="record a bag of every trial (default: the "
                                                                    "protocol's record.bag)")
    p.add_argument("--realtime", action="store_true", help="scripted subjects too walk in real time (default: "
                                                           "lockstep, as fast as the machine allows)")
    p.add_argument("--other-representation", action="store_true",
                   help="run a learned patient on phosphenes it was not trained on (refused otherwise; the "
                        "records say other_representation: true)")
    p = sub.add_parser("sweep", help="many scripted-subject sessions in parallel (worker processes or Ray)")
    p.add_argument("sweep")
    p.add_argument("--out", default=None, help="output folder (default: sweeps/<sweep name>)")
    p.add_argument("--workers", type=int, default=None, help="worker processes on this machine (default: cores / 2)")
    p.add_argument("--ray", nargs="?", const="local", default=None, metavar="ADDRESS",
                   help="run on a Ray cluster (ADDRESS, e.g. auto or ray://host:10001; no ADDRESS: a local Ray)")
    p.add_argument("--resume", action="store_true", help="continue sessions already in OUT")
    p.add_argument("--domains", default=None, metavar="LOW-HIGH",
                   help="ROS domain ids the sweep's graphs may take, e.g. 100-140 (default: 30-230, any free one)")
    p = sub.add_parser("quick-sweep", help="a sweep's trials in one process from the cores (quick_trial; spv-only "
                                           "conditions), one CSV row per trial and a summary with bootstrap CIs")
    p.add_argument("sweep")
    p.add_argument("--out", default=None, help="CSV file (default: sweeps/<sweep name>/quick_trials.csv)")
    p.add_argument("--subjects", default=None, metavar="N,N,...", help="only these virtual subjects of the sweep")
    p.add_argument("--figure", default=None, metavar="DIR",
                   help="also draw the summary per level (success, time, collisions with CIs) into DIR/levels.png, .pdf; "
                        "over several factors every cell, into DIR/cells.png")
    p.add_argument("--summarise", nargs="+", default=None, metavar="CSV",
                   help="run nothing: summarise these quick-sweep CSVs (e.g. one per --subjects process)")
    p = sub.add_parser("report", help="tidy CSV and HTML report with figures and statistics")
    p.add_argument("dirs", nargs="+", metavar="DIR", help="session or sweep folders (searched for trials.jsonl)")
    p.add_argument("-o", "--out", default="report", help="output folder (default: report)")
    p.add_argument("--title", default=None)
    p.add_argument("--pool", action="store_true", help="pool sessions of different protocols (refused otherwise); "
                                                       "subjects become protocol/subject")
    p.add_argument("--share-threshold", type=float, default=None, metavar="FRACTION",
                   help="flag trials whose share of frames in their own representation is below this "
                        "(default 0.995)")


def _err(text: str) -> int:
    print(f"raspv experiment: {text}", file=sys.stderr)
    return 2


def run(args: argparse.Namespace) -> int:
    from raspv_sim.native_output import captured_native_output

    with captured_native_output():      # PyBullet's import banner is not for the experimenter
        import pybullet  # noqa: F401
    return {"check": _check, "plan": _plan, "run": _run, "sweep": _sweep, "quick-sweep": _quick_sweep,
            "report": _report}[args.action](args)


def _load(name: str, warn: bool = True):
    from raspv_experiments.protocol import load_protocol, resolve_protocol_path

    protocol = load_protocol(resolve_protocol_path(name))
    if warn and protocol.name != protocol.path.stem:
        print(f"raspv experiment: warning: {protocol.path}: name: {protocol.name!r} is not the file's name "
              f"({protocol.path.stem!r}): its sessions go to <out>/{protocol.name}/ — beside any other protocol of "
              "that name (a copied file keeps the original's name: change it)", file=sys.stderr)
    return protocol


def _check(args) -> int:
    from raspv_experiments.protocol import ProtocolError
    from raspv_experiments.sweep import load_sweep

    from raspv_experiments.protocol import resolve_protocol_path

    code = 0
    for f in args.files:
        try:
            if _is_sweep(resolve_protocol_path(f)):
                s = load_sweep(resolve_protocol_path(f))
                print(f"ok: {f}: sweep of {len(s.subjects)} virtual subjects × {len(s.protocol.conditions)} conditions")
            else:
                p = _load(f)
                print(f"ok: {p.path}: {len(p.conditions)} conditions × {len(p.tasks)} tasks × "
                      f"{p.design.repetitions} repetitions, order {p.design.order}")
        except ProtocolError as exc:
            for line in exc.errors:
                print(line, file=sys.stderr)
            code = 2
    return code


def _is_sweep(path: Path) -> bool:
    """A sweep file names a protocol; a protocol file has a graph."""
    import yaml

    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return False
    return isinstance(doc, dict) and "protocol" in doc and "graph" not in doc


def _plan(args) -> int:
    from raspv_experiments.design import plan_session
    from raspv_experiments.protocol import ProtocolError

    from raspv_experiments.session_runner import parse_subject

    try:
        protocol = _load(args.protocol)
        subject, _, _ = parse_subject(args.subject)
        trials = plan_session(protocol, subject)
    except ProtocolError as exc:
        print("\n".join(exc.errors), file=sys.stderr)
        return 2
    except ValueError as exc:
        return _err(str(exc))
    for t in trials:
        mark = "  (break before)" if t.break_before else ""
        print(f"{t.index:3d}  block {t.block}  {t.label}{mark}")
    return 0


def _install_stop(stop: threading.Event) -> None:
    def handler(signum, _frame):
        stop.set()
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


def _run(args) -> int:
    from raspv_bringup.middleware import apply_middleware_defaults
    from raspv_experiments.protocol import ProtocolError
    from raspv_experiments.runner_node import RunnerError
    from raspv_experiments.session import SessionError
    from raspv_experiments.session_runner import RunOptions, SessionRunner, parse_subject
    from raspv_experiments.terminal import TerminalView

    try:
        protocol = _load(args.protocol)
        subject, policy, number = parse_subject(args.subject)
    except ProtocolError as exc:
        print("\n".join(exc.errors), file=sys.stderr)
        return 2
    except ValueError as exc:
        return _err(str(exc))
    apply_middleware_defaults()
    options = RunOptions(out=Path(args.out), subject=subject, policy=policy, number=number, resume=args.resume,
                         bag=args.bag, lockstep=False if args.realtime else None,
                         headless=False if args.realtime else None, other_representation=args.other_representation)
    holder: dict = {}
    view = TerminalView(on_key=lambda key: holder["runner"].control.key(key) if "runner" in holder else None)
    runner = None
    _install_stop(options.stop)
    try:
        runner = holder["runner"] = SessionRunner(protocol, options, view)
        return runner.run()
    except (SessionError, RunnerError, ValueError) as exc:
        view.say("")
        return _err(str(exc))
    except KeyboardInterrupt:
        view.say("raspv experiment: stopped; continue with --resume")
        return 130
    finally:
        if runner is not None:
            runner.close()
        view.close()


def _load_sweep(name: str):
    """The sweep file ``name`` (a path or a file in ``experiments/``), or None after printing
    its mistakes (one line each)."""
    from raspv_experiments.protocol import ProtocolError, resolve_protocol_path
    from raspv_experiments.sweep import load_sweep

    try:
        return load_sweep(resolve_protocol_path(name))
    except ProtocolError as exc:
        print("\n".join(exc.errors), file=sys.stderr)
        return None


def _sweep(args) -> int:
    from raspv_experiments.protocol import ProtocolError
    from raspv_experiments.sweep import run_sweep

    sweep = _load_sweep(args.sweep)
    if sweep is None:
        return 2
    out = Path(args.out or f"sweeps/{sweep.name}")
    if args.workers is not None and args.workers < 1:
        return _err(f"--workers must be >= 1, got {args.workers}")
    domains = None
    if args.domains is not None:
        try:
            low, high = (int(v) for v in args.domains.split("-"))
            if not 0 <= low < high <= 233:
                raise ValueError
        except ValueError:
            return _err(f"--domains {args.domains}: expected LOW-HIGH with 0 <= LOW < HIGH <= 233 (Fast DDS ports), "
                        "e.g. 100-140")
        domains = (low, high)
    try:
        results = run_sweep(sweep, out, args.workers, args.ray, args.resume, domains=domains)
    except ProtocolError as exc:
        print("\n".join(exc.errors), file=sys.stderr)
        return 2
    bad = [r for r in results if r["code"] != 0]
    stopped = [r for r in results if r.get("error")]
    if stopped:
        print(f"sweep stopped: {len(stopped)} of {len(results)} sessions did not finish ({stopped[0]['subject']}: "
              f"{stopped[0]['error']}); continue them with: raspv experiment sweep {args.sweep} --resume"
              + (f" --out {args.out}" if args.out else ""), file=sys.stderr)
        return 1
    print(f"sweep done: {len(results)} sessions in {out / 'sessions'}; report: raspv experiment report {out}")
    return 1 if bad else 0


def _quick_sweep(args) -> int:
    from raspv_experiments.quick_sweep import check_quick, read_quick_csv, run_quick_sweep, summarise, summary_table

    sweep = _load_sweep(args.sweep)
    if sweep is None:
        return 2
    if args.subjects:
        try:
            sweep.subjects = [int(v) for v in args.subjects.split(",")]
        except ValueError:
            return _err(f"--subjects {args.subjects}: expected numbers separated by commas, e.g. 1,2,3")
    problems = check_quick(sweep)
    if problems:
        print("\n".join(problems), file=sys.stderr)
        return 2
    if args.summarise:
        try:
            records = read_quick_csv(args.summarise)
        except (OSError, ValueError) as exc:
            return _err(str(exc))
        out = ", ".join(args.summarise)
    else:
        out = Path(args.out or f"sweeps/{sweep.name}/quick_trials.csv")
        records = run_quick_sweep(sweep, out)
    limits = {t.name: t.time_limit for t in sweep.protocol.tasks}
    if len(sweep.protocol.factors) > 1:
        _summarise_cells(sweep, records, limits, args.figure)
        print(f"trials: {out}")
        return 0
    factor = next(iter(sweep.protocol.factors), None)
    levels = sweep.protocol.factors.get(factor)
    summaries = summarise(records, limits, factor, levels)
    print(summary_table(summaries, factor or "condition"))
    if args.figure:
        from raspv_experiments.report_figures import level_summaries

        png = level_summaries(summaries, factor or "condition", Path(args.figure), title=sweep.name)
        print(f"figure: {Path(args.figure).parent / png}")
    if factor and levels and len(levels) >= 3:
        _print_trend(records, limits, factor, [str(v) for v in levels], "")
    print(f"trials: {out}")
    return 0


def _print_trend(records, limits, factor: str, levels: list[str], where: str) -> None:
    from raspv_experiments.trend import ordered_trends, trend_table

    try:
        print(f"\nTrend over {factor}{where} (in the sweep file's order; raspv_experiments/trend.py):")
        print(trend_table(ordered_trends(records, limits, factor, levels), factor))
    except ValueError as exc:
        print(f"no trend: {exc}")


def _summarise_cells(sweep, records, limits, figure: str | None) -> None:
    """A sweep over several factors: every cell (combination of levels) summarised and drawn,
    and the trend over the first factor within each combination of the others."""
    from raspv_experiments.quick_sweep import summarise, summary_table

    factors = list(sweep.protocol.factors)
    cells = {c.name: {f: str(c.factors.get(f, "")) for f in factors} for c in sweep.protocol.conditions}
    summaries = summarise(records, limits, None, [c.name for c in sweep.protocol.conditions])
    print(summary_table(summaries, "condition", cells))
    if figure:
        from raspv_experiments.report_figures import cell_summaries

        png = cell_summaries(summaries, cells, factors, Path(figure), title=sweep.name)
        print(f"figure: {Path(figure).parent / png}")
    first, levels = factors[0], [str(v) for v in sweep.protocol.factors[factors[0]]]
    if len(levels) >= 3:
        others = dict.fromkeys(tuple(cell[f] for f in factors[1:]) for cell in cells.values())
        for combination in others:
            names = {n for n, cell in cells.items() if tuple(cell[f] for f in factors[1:]) == combination}
            where = ", ".join(f"{f}={v}" for f, v in zip(factors[1:], combination))
            _print_trend([r for r in records if r.condition in names], limits, first, levels, f" at {where}")


def _report(args) -> int:
    from raspv_experiments.report import ReportError, build_report

    from raspv_common.shown_share import DEFAULT_THRESHOLD

    threshold = DEFAULT_THRESHOLD if args.share_threshold is None else args.share_threshold
    if not 0.0 <= threshold <= 1.0:
        return _err(f"--share-threshold must be a fraction in [0, 1], got {threshold}")
    try:
        path = build_report([Path(d) for d in args.dirs], Path(args.out), args.title, pool=args.pool,
                            share_threshold=threshold)
    except ReportError as exc:
        return _err(str(exc))
    print(f"report: {path} (data: {path.parent / 'trials.csv'})")
    return 0
