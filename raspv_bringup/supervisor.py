"""Run a graph: one process per node, supervised, shut down cleanly (no rclpy).

Each node runs as ``python -m raspv_bringup.node_entry <module> --ros-args -r __node:=<name>
--params-file <file>`` in its own process group, with the parent-death signal set so it never
outlives the launcher. Every output line goes to the node's log file
(``~/.ros/log/raspv_launch_…/<node>.log``, see :mod:`raspv_bringup.node_output`) and, prefixed
with the node name, to the terminal — except Python tracebacks, which the terminal sees as one
line naming the exception and the log file. A node that dies stops the graph (or is restarted,
at once, when its entry says ``restart: true``). On SIGINT/SIGTERM every node gets SIGINT, then
SIGTERM, then SIGKILL if it ignores them. At the end each node's peak resident memory, CPU time
(from ``wait4``'s rusage), restarts and the reason of the last one are printed.
"""
from __future__ import annotations

import ctypes
import os
import select
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
from raspv_bringup.node_output import NodeLog, TracebackSummariser, new_launch_log_dir
from raspv_bringup.warm_spare import WarmSpare
from raspv_common.startup_timing import SPAWN_TIME_ENV

_libc = ctypes.CDLL(None, use_errno=True)
_PR_SET_PDEATHSIG = 1
MAX_RESTARTS = 5          # within RESTART_WINDOW_S, then the graph stops
RESTART_WINDOW_S = 60.0
SPARE_DELAY_S = 5.0       # a warm spare is started this long after its node, not competing with its start
MAX_SPARE_FAILURES = 2    # spares that die unasked before this node gets no more of them


def stop_with_parent() -> None:  # runs in a child between fork and exec
    """SIGTERM to this process when the one that started it dies (PR_SET_PDEATHSIG): a killed
    launcher, benchmark or test leaves nothing running."""
    _libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)


def _die_with_parent() -> None:  # runs in the child between fork and exec
    stop_with_parent()
    # SIGINT stays pending until node_entry is ready to turn it into a quiet exit: delivered
    # while the interpreter itself starts, it aborts with a "Fatal Python error" report.
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})


def exit_reason(code: int | None) -> str:
    """``killed by signal 9`` / ``exit code 1``."""
    return f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"


@dataclass
class NodeProcess:
    entry: NodeEntry
    params_path: Path
    log: NodeLog | None = None
    proc: subprocess.Popen | None = None
    exit_code: int | None = None
    peak_rss_kb: int = 0
    cpu_s: float = 0.0
    restarts: list[float] = field(default_factory=list)   # monotonic times within RESTART_WINDOW_S
    restart_count: int = 0
    last_restart_reason: str = ""
    started_at: float = 0.0                                # monotonic time of the current process's spawn
    pidfd: int | None = None
    reader: threading.Thread | None = None
    spare: WarmSpare | None = None                         # imports done, waiting to take over
    spare_failures: int = 0


class Supervisor:
    """Starts, watches and stops the processes of a :class:`Graph`."""

    def __init__(self, graph: Graph, out: IO[str] | None = None, shutdown_timeout_s: float = 8.0,
                 python: str | None = None, log_dir: Path | None = None) -> None:
        self.graph = graph
        self.out = out or sys.stdout
        self.shutdown_timeout_s = shutdown_timeout_s
        self.python = python or sys.executable
        self._tmp = tempfile.TemporaryDirectory(prefix="raspv-launch-")
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._stopping = False           # nodes' KeyboardInterrupts are expected from now on
        self.env = middleware_env(os.environ, graph.env)
        self.log_dir = log_dir or new_launch_log_dir(self.env)
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.nodes: list[NodeProcess] = []
        for entry in graph.nodes:
            path = Path(self._tmp.name) / f"{entry.name}.yaml"
            path.write_text(node_params_file(entry))
            self.nodes.append(NodeProcess(entry, path, NodeLog(self.log_dir / f"{entry.name}.log")))

    # -- output ----------------------------------------------------------------------------
    def say(self, text: str) -> None:
        with self._lock:
            self.out.write(text + "\n")
            self.out.flush()

    def _pump(self, node: NodeProcess, stream: IO[bytes]) -> None:
        """Copy one process's output to its log file and, without tracebacks, to the terminal."""
        prefix = f"[{node.entry.name}] "
        log = node.log
        filt = TracebackSummariser(str(log.path) if log else "the node's log", quiet=self._expected_while_stopping)
        for raw in iter(stream.readline, b""):
            line = raw.decode("utf-8", "replace").rstrip("\n")
            if log is not None:
                log.write(line)
            shown = filt.feed(line)
            if shown is not None:
                self.say(prefix + shown)
        tail = filt.flush()
        if tail is not None:
            self.say(prefix + tail)
        stream.close()

    def _expected_while_stopping(self, exception_line: str, ignored: bool) -> bool:
        """While the graph stops, a node's KeyboardInterrupt and errors of objects torn down
        half-built ("Exception ignored in …") are expected: they stay in its log only."""
        return self._stopping and (ignored or exception_line.startswith("KeyboardInterrupt"))

    # -- processes -------------------------------------------------------------------------
    def command(self, node: NodeProcess, spare: bool = False) -> list[str]:
        return [self.python, "-m", "raspv_bringup.node_entry", *(["--spare"] if spare else []), node.entry.module,
                "--ros-args", "-r", f"__node:={node.entry.name}", "--params-file", str(node.params_path)]

    def _popen(self, node: NodeProcess, spare: bool) -> tuple[subprocess.Popen, threading.Thread]:
        env = dict(self.env)
        env.update(node.entry.env)
        env["PYTHONUNBUFFERED"] = "1"
        env[SPAWN_TIME_ENV] = repr(time.time())          # start-up timing (raspv_common.startup_timing)
        proc = subprocess.Popen(self.command(node, spare), env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, stdin=subprocess.PIPE if spare else subprocess.DEVNULL,
                                start_new_session=True, preexec_fn=_die_with_parent)
        reader = threading.Thread(target=self._pump, args=(node, proc.stdout), daemon=True)
        reader.start()
        return proc, reader

    def _spawn(self, node: NodeProcess) -> None:
        node.started_at = time.monotonic()
        node.proc, node.reader = self._popen(node, spare=False)
        node.exit_code = None
        if node.log is not None:
            node.log.mark(f"started pid {node.proc.pid}: {' '.join(self.command(node))}")
        node.pidfd = _pidfd(node.proc.pid)

    def _take_over_from_spare(self, node: NodeProcess) -> bool:
        """Make the node's warm spare its process (False: no usable spare)."""
        spare, node.spare = node.spare, None
        if spare is None or not spare.promote():
            if spare is not None:
                self._collect_spare(node, spare)
            return False
        node.started_at = time.monotonic()
        node.proc, node.reader, node.exit_code = spare.proc, spare.reader, None
        node.pidfd = _pidfd(node.proc.pid)
        if node.log is not None:
            node.log.mark(f"warm spare pid {node.proc.pid} took over")
        return True

    def _keep_spares(self) -> None:
        """Start a warm spare for every node that should have one (SPARE_DELAY_S after the node
        started, so it does not slow the node's own start); notice spares that died."""
        now = time.monotonic()
        for node in self.nodes:
            if node.spare is not None and not node.spare.alive:
                code = self._collect_spare(node, node.spare)
                node.spare = None
                node.spare_failures += 1
                self.say(f"raspv launch: the warm spare of '{node.entry.name}' ended ({exit_reason(code)})"
                         + ("; restarts start cold" if node.spare_failures >= MAX_SPARE_FAILURES else ""))
            if (node.entry.spare and node.spare is None and node.exit_code is None and node.proc is not None
                    and node.spare_failures < MAX_SPARE_FAILURES and now - node.started_at >= SPARE_DELAY_S):
                proc, reader = self._popen(node, spare=True)
                node.spare = WarmSpare(proc, reader, now)
                if node.log is not None:
                    node.log.mark(f"warm spare pid {proc.pid} started")

    def _collect_spare(self, node: NodeProcess, spare: WarmSpare) -> int | None:
        """End ``spare`` and count its memory and CPU time as the node's."""
        rss_kb, cpu_s = spare.discard()
        node.peak_rss_kb = max(node.peak_rss_kb, rss_kb)
        node.cpu_s += cpu_s
        if spare.reader is not None:
            spare.reader.join(timeout=1.0)
        return spare.proc.returncode

    def start(self) -> None:
        for node in self.nodes:
            self._spawn(node)
        names = ", ".join(f"{n.entry.name} ({n.entry.kind}, pid {n.proc.pid})" for n in self.nodes)
        self.say(f"raspv launch: started {len(self.nodes)} nodes from {self.graph.path}: {names}")
        self.say(f"raspv launch: each node's full output is logged in {self.log_dir}/")

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
        if node.pidfd is not None:
            os.close(node.pidfd)
            node.pidfd = None
        if node.log is not None:
            node.log.mark(f"pid {node.proc.pid} ended ({exit_reason(node.exit_code)})")
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
                            self._stopping = True
                            self._stop.set()
                            break
                self._keep_spares()
                self._wait_for_an_exit(0.1)
        finally:
            self.shutdown()
        if code:
            self.say(f"raspv launch: the full output of every node is in {self.log_dir}/")
        return code

    def _wait_for_an_exit(self, timeout_s: float) -> None:
        """Sleep until a node process ends (its pidfd becomes readable) or ``timeout_s`` passes,
        so a dead node is seen, and restarted, at once rather than at the next poll."""
        fds = [n.pidfd for n in self.nodes if n.pidfd is not None and n.exit_code is None]
        if not fds:
            self._stop.wait(timeout_s)
            return
        try:
            select.select(fds, [], [], timeout_s)
        except (OSError, ValueError):        # a pidfd closed meanwhile
            self._stop.wait(timeout_s)

    def _handle_exit(self, node: NodeProcess) -> bool:
        """Report a node that ended; restart it if allowed. False means: stop the graph."""
        why = exit_reason(node.exit_code)
        now = time.monotonic()
        node.restarts = [t for t in node.restarts if now - t < RESTART_WINDOW_S] + [now]
        if not node.entry.restart or len(node.restarts) > MAX_RESTARTS:
            if node.reader is not None:           # its last lines (the reason) come before ours
                node.reader.join(timeout=2.0)
        if not node.entry.restart:
            self.say(f"raspv launch: node '{node.entry.name}' ended ({why}); stopping the graph")
            return False
        if len(node.restarts) > MAX_RESTARTS:
            self.say(f"raspv launch: node '{node.entry.name}' ended ({why}) {MAX_RESTARTS} times within "
                     f"{RESTART_WINDOW_S:.0f} s; stopping the graph")
            return False
        node.restart_count += 1
        node.last_restart_reason = why
        if self._take_over_from_spare(node):
            self.say(f"raspv launch: node '{node.entry.name}' ended ({why}); restarting it (warm spare, pid {node.proc.pid})")
        else:
            self._spawn(node)
            self.say(f"raspv launch: node '{node.entry.name}' ended ({why}); restarting it (pid {node.proc.pid})")
        if node.exit_code is not None and node.exit_code < 0:
            self._clean_shared_memory()         # a killed process leaves its DDS segment behind
        return True

    def _clean_shared_memory(self) -> None:
        """Remove shared-memory segments whose owner died (:mod:`raspv_bringup.shm_cleanup`)."""
        from raspv_bringup.shm_cleanup import remove_stale_segments
        cleanup = remove_stale_segments()
        if cleanup.removed:
            self.say(f"raspv launch: {cleanup.describe()}")

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
        self._stopping = True
        for node in self.nodes:                 # unused spares: closing stdin makes them exit
            if node.spare is not None and node.spare.proc.stdin:
                try:
                    node.spare.proc.stdin.close()
                except OSError:
                    pass
        self._signal_all(signal.SIGINT)
        if not self._wait_all(self.shutdown_timeout_s):
            slow = [n.entry.name for n in self.nodes if n.exit_code is None]
            self.say(f"raspv launch: {', '.join(slow)} did not stop on SIGINT; sending SIGTERM")
            self._signal_all(signal.SIGTERM)
            if not self._wait_all(3.0):
                self._signal_all(signal.SIGKILL)
                for n in self.nodes:
                    self._reap(n, block=True)
        for node in self.nodes:
            if node.spare is not None:
                self._collect_spare(node, node.spare)
                node.spare = None
        # Anything a node left behind in its process group goes too.
        for node in self.nodes:
            if node.proc is not None:
                try:
                    os.killpg(node.proc.pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass
        for node in self.nodes:
            if node.reader is not None:
                node.reader.join(timeout=2.0)
            if node.pidfd is not None:
                os.close(node.pidfd)
                node.pidfd = None
            if node.log is not None:
                node.log.close()
        if any(n.restart_count or (n.exit_code is not None and n.exit_code < 0) for n in self.nodes):
            self._clean_shared_memory()
        self.say(self.resource_table())
        self._tmp.cleanup()

    def resource_table(self) -> str:
        """Per node: exit code, peak resident memory over all its processes, CPU time, restarts
        and why the last restart happened."""
        rows = [f"{'node':<16} {'kind':<12} {'exit':>5} {'peak RSS MB':>12} {'CPU s':>8} {'restarts':>9}  last restart"]
        total_mb = 0.0
        for n in self.nodes:
            mb = n.peak_rss_kb / 1024.0
            total_mb += mb
            rows.append(f"{n.entry.name:<16} {n.entry.kind:<12} {str(n.exit_code):>5} {mb:>12.0f} {n.cpu_s:>8.1f} "
                        f"{n.restart_count:>9}  {n.last_restart_reason or '-'}")
        rows.append(f"{'total':<16} {'':<12} {'':>5} {total_mb:>12.0f} {sum(n.cpu_s for n in self.nodes):>8.1f} "
                    f"{sum(n.restart_count for n in self.nodes):>9}")
        return "raspv launch: resources per node\n" + "\n".join(rows)


def _pidfd(pid: int) -> int | None:
    """A file descriptor that becomes readable when process ``pid`` ends (Linux ≥ 5.3)."""
    try:
        return os.pidfd_open(pid)
    except (AttributeError, OSError):
        return None
