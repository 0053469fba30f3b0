"""`raspv doctor`: one screen saying what this machine can do, each gap with its fix."""
from __future__ import annotations

import argparse
import time

MARKS = {"ok": "ok ", "gap": "-- ", "fail": "!! "}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--clean-shm", action="store_true",
                        help="first remove the shared-memory segments killed processes left in /dev/shm")


def run(args: argparse.Namespace) -> int:
    from raspv_bringup.doctor import run_checks

    t0 = time.perf_counter()
    if args.clean_shm:
        from raspv_bringup.shm_cleanup import remove_stale_segments

        print(f"raspv doctor: {remove_stale_segments().describe()}")
    checks = run_checks()
    width = max(len(c.name) for c in checks)
    print("raspv doctor: what this machine can do (ok: ready, --: a gap some features need, !!: graphs cannot run)")
    for c in checks:
        print(f"  {MARKS[c.status]}{c.name:<{width}}  {c.detail}")
        if c.fix and c.status != "ok":
            print(f"     {'':<{width}}  fix: {c.fix}")
    failed = [c.name for c in checks if c.status == "fail"]
    gaps = [c.name for c in checks if c.status == "gap"]
    verdict = (f"cannot run graphs until fixed: {', '.join(failed)}" if failed else
               f"ready; gaps: {', '.join(gaps)}" if gaps else "ready; no gaps")
    print(f"raspv doctor: {verdict} ({time.perf_counter() - t0:.1f} s)")
    return 1 if failed else 0
