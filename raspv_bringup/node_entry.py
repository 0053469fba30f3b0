"""The program every node process of a graph runs: ``python -m raspv_bringup.node_entry MODULE ARGS…``.

It imports the node module and calls its ``main(argv)``. A SIGINT that lands while the module
is still importing — seconds for nodes that import SciPy, Open3D or PyBullet, and exactly when
a launch that fails stops its other nodes — ends the process quietly with exit code 130
instead of a ``KeyboardInterrupt`` traceback (also when a C extension turns the interrupt into an
``ImportError``, :func:`interrupted`); the launcher starts nodes with SIGINT blocked so
that one arriving while the interpreter itself starts waits until this module unblocks it.
(Once ``main`` runs, ``run_node`` handles SIGINT as a clean stop.)

``--spare MODULE …``: a warm spare (:mod:`raspv_bringup.warm_spare`): import, then wait for a
line on stdin before running the node. No rclpy here.
"""
from __future__ import annotations

import importlib
import os
import signal
import sys

from raspv_common.extras import MissingExtra
from raspv_common.startup_timing import SPAWN_TIME_ENV, startup_mark

INTERRUPTED = 130


def main(argv: list[str] | None = None) -> None:
    startup_mark("interpreter ready")
    argv = list(sys.argv[1:] if argv is None else argv)
    spare = bool(argv) and argv[0] == "--spare"
    if spare:
        argv = argv[1:]
    if not argv:
        print("usage: python -m raspv_bringup.node_entry [--spare] NODE_MODULE [--ros-args ...]", file=sys.stderr)
        sys.exit(2)
    module_name, rest = argv[0], argv[1:]
    try:
        # The launcher starts nodes with SIGINT blocked (a SIGINT during the interpreter's own
        # start-up is a fatal error); from here on it is a KeyboardInterrupt, even when the
        # launcher runs as a background job (whose children inherit SIGINT ignored).
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        module = importlib.import_module(module_name)
        startup_mark("imports done")
        if spare:
            _wait_for_promotion()
    except KeyboardInterrupt:
        _exit_quietly()
    except MissingExtra as exc:           # the node needs an extra: one line naming its install
        print(f"{module_name}: {exc}", file=sys.stderr)
        sys.exit(1)
    except ImportError as exc:
        if not interrupted(exc):
            raise
        _exit_quietly()
    try:
        module.main([module_name, *rest])
    except KeyboardInterrupt:             # between the import and run_node's own handling
        _exit_quietly()
    except ImportError as exc:            # a module imported late (inside main), interrupted
        if not interrupted(exc):
            raise
        _exit_quietly()


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` was caused by a KeyboardInterrupt: a C extension whose module init is
    interrupted reports it as ``ImportError: initialization failed`` chained from the
    KeyboardInterrupt (pybind11; measured with rclpy's ``_rclpy_pybind11``: a SIGINT during the
    bridge's import of rclpy left that traceback in its log, CI of the clean-shutdown test)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _wait_for_promotion() -> None:
    """A warm spare (``raspv_bringup.warm_spare``) waits here until the launcher writes the time
    it promoted the spare (start-up times count from then) or closes stdin (not needed: exit)."""
    line = sys.stdin.readline()
    if not line.strip():
        sys.stdout.flush()
        os._exit(0)
    os.environ[SPAWN_TIME_ENV] = line.strip()
    startup_mark("promoted from warm spare")


def _exit_quietly() -> None:
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(INTERRUPTED)             # no interpreter teardown: half-imported C extensions


if __name__ == "__main__":
    main()
