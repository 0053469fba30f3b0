"""Run a graph: one process per node, supervised, shut down cleanly (no rclpy).

Each node runs as ``python -m <module> --ros-args -r __node:=<name> --params-file <file>`` in
its own process group, with the parent-death signal set so it never outlives the launcher.
Output lines are prefixed with the node name. A node that dies stops the graph (or is
restarted when its entry says ``restart: true``). On SIGINT/SIGTERM every node gets SIGINT,
then SIGTERM, then SIGKILL if it ignores them. At the end each node's peak resident memory and
CPU time (from ``wait4``'s rusage) are printed.
"""
from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Callable

from raspv_bringup.graph import Graph, NodeEntry, node_params_file
from raspv_bringup.middleware import middleware_env

_libc = ctypes.CDLL(None, use_errno=True)
_PR_SET_PDEATHSIG = 1
MAX_RESTARTS = 5          # within RESTART_WINDOW_S, then the graph stops
RESTART_WINDOW_S = 60.0


def _die_with_parent() -> None:  # runs in the child between fork and exec
    _libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)


@dataclass
class NodeProcess:
    entry: NodeEntry
    params_path: Path
    proc: subprocess.Popen | None = None
    exit_code: int | None = None
    peak_rss_kb: int = 0
    cpu_s: float = 0.0
    restarts: list[float] = field(default_factory=list)
    reader: threading.Thread | None = None


class Supervisor:
    """Starts, watches and stops the processes of a :class:`Graph`."""

    def __init__(self, graph: Graph, out: IO[str] | None = None, shutdown_timeout_s: float = 8.0,
                 python: str | None = None) -> None:
        self.graph = graph
        self.out = out or sys.stdout
        self.shutdown_timeout_s = shutdown_timeout_s
        self.python = python or sys.executable
        self._tmp = tempfile.TemporaryDirectory(prefix="raspv-launch-")
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.nodes: list[NodeProcess] = []
        for entry in graph.nodes:
            path = Path(self._tmp.name) / f"{entry.name}.yaml"
            path.write_text(node_params_file(entry))
            self.nodes.append(NodeProcess(entry, path))
        self.env = middleware_env(os.environ, graph.env)

    # -- output ----------------------------------------------------------------------------
    def say(self, text: str) -> None:
        with self._lock:
            self.out.write(text + "\n")
            self.out.flush()

    def _pump(self, node: NodeProcess, stream: IO[bytes]) -> None:
        prefix = f"[{node.entry.name}] "
        for raw in iter(stream.readline, b""):
            line = raw.decode("utf-8", "replace").rstrip("\n")
            with self._lock:
                self.out.write(prefix + line + "\n")
                self.out.flush()
        stream.close()

    # -- processes -------------------------------------------------------------------------
    def command(self, node: NodeProcess) -> list[str]:
        return [self.python, "-m", node.entry.module, "--ros-args", "-r", f"__node:={node.entry.name}",
                "--params-file", str(node.params_path)]

    def _spawn(self, node: NodeProcess) -> None:
        env = dict(self.env)
        env.update(node.entry.env)
        env["PYTHONUNBUFFERED"] = "1"
        node.proc = subprocess.Popen(self.command(node), env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                     start_new_session=True, preexec_fn=_die_with_parent)
        node.exit_code = None
        node.reader = threading.Thread(target=self._pump, args=(node, node.proc.stdout), daemon=True)
        node.reader.start()

    def start(self) -> None:
        for node in self.nodes:
            self._spawn(node)
        names = ", ".join(f"{n.entry.name} ({n.entry.kind}, pid {n.proc.pid})" for n in self.nodes)
        self.say(f"raspv launch: started {len(self.nodes)} nodes from {self.graph.path}: {names}")

    def _reap(self, node: NodeProcess, block: bool = False) -> bool:
        """Collect the exit status and rusage of ``node``'s process if it ended."""
        if node.proc is None or node.exit_code is not None:
            return node.exit_code is not None
        try:
            pid, status, usage = os.wait4(node.proc.pid, 0 if block else os.WNOHANG)
        except ChildProcessError:
            node.exit_code = node.proc.returncode if node.proc.returncode is not None else -1
            return True
        if pid == 0:
            return False
        node.exit_code = os.waitstatus_to_exitcode(status)
        node.proc.returncode = node.exit_code
        node.peak_rss_kb = max(node.peak_rss_kb, int(usage.ru_maxrss))
        node.cpu_s += usage.ru_utime + usage.ru_stime
        if node.reader is not None:
            node.reader.join(timeout=2.0)
        return True

    def request_stop(self) -> None:
        self._stop.set()

    def run(self, should_continue: Callable[[], bool] = lambda: True) -> int:
        """Supervise until a stop request (signal) or a node dies. Returns the exit code:
        0 after a requested stop, 1 when a node died and was not restarted."""
        code = 0
        try:
            while not self._stop.is_set() and should_continue():
                for node in self.nodes:
                    if node.exit_code is None and self._reap(node):
                        if not self._handle_exit(node):
                            code = 1
                            self._stop.set()
                            break
                self._stop.wait(0.1)
        finally:
            self.shutdown()
        return code

    def _handle_exit(self, node: NodeProcess) -> bool:
        """Report a node that ended; restart it if allowed. False means: stop the graph."""
        code = node.exit_code
        why = f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"
        if not node.entry.restart:
            self.say(f"raspv launch: node '{node.entry.name}' ended ({why}); stopping the graph")
            return False
        now = time.monotonic()
        node.restarts = [t for t in node.restarts if now - t < RESTART_WINDOW_S] + [now]
        if len(node.restarts) > MAX_RESTARTS:
            self.say(f"raspv launch: node '{node.entry.name}' ended ({why}) {MAX_RESTARTS} times within "
                     f"{RESTART_WINDOW_S:.0f} s; stopping the graph")
            return False
        self.say(f"raspv launch: node '{node.entry.name}' ended ({why}); restarting it")
        self._spawn(node)
        return True

    def _signal_all(self, sig: int) -> None:
        for node in self.nodes:
            if node.proc is not None and node.exit_code is None:
                try:
                    os.killpg(node.proc.pid, sig)
                except (ProcessLookupError, PermissionError):
                    pass

    def _wait_all(self, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if all(self._reap(n) for n in self.nodes):
                return True
            time.sleep(0.05)
        return all(self._reap(n) for n in self.nodes)

    def shutdown(self) -> None:
        """SIGINT every node, then SIGTERM, then SIGKILL; reap all; print the resource table."""
        self._signal_all(signal.SIGINT)
        if not self._wait_all(self.shutdown_timeout_s):
            slow = [n.entry.name for n in self.nodes if n.exit_code is None]
            self.say(f"raspv launch: {', '.join(slow)} did not stop on SIGINT; sending SIGTERM")
            self._signal_all(signal.SIGTERM)
            if not self._wait_all(3.0):
                self._signal_all(signal.SIGKILL)
                for n in self.nodes:
                    self._reap(n, block=True)
        # Anything a node left behind in its process group goes too.
        for node in self.nodes:
            if node.proc is not None:
                try:
                    os.killpg(node.proc.pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass
        self.say(self.resource_table())
        self._tmp.cleanup()

    def resource_table(self) -> str:
        rows = [f"{'node':<16} {'kind':<12} {'exit':>5} {'peak RSS MB':>12} {'CPU s':>8}"]
        total_mb = 0.0
        for n in self.nodes:
            mb = n.peak_rss_kb / 1024.0
            total_mb += mb
            rows.append(f"{n.entry.name:<16} {n.entry.kind:<12} {str(n.exit_code):>5} {mb:>12.0f} {n.cpu_s:>8.1f}")
        rows.append(f"{'total':<16} {'':<12} {'':>5} {total_mb:>12.0f} {sum(n.cpu_s for n in self.nodes):>8.1f}")
        return "raspv launch: resources per node\n" + "\n".join(rows)
