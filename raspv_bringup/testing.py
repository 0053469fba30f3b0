"""Test harness: private ROS domains, graphs in subprocesses, and a probe node.

- :func:`claim_private_domain` picks a ``ROS_DOMAIN_ID`` no other test session on this machine
  holds (a lock file per id), so parallel runs never cross-talk.
- :class:`RunningGraph` runs ``raspv launch`` on a graph (dict or file) in a subprocess,
  captures its output and stops it with SIGINT, checking that no process is left behind.
- :class:`Probe` is an rclpy node spinning in a background thread of the test process: it
  waits for messages (never fixed sleeps), collects them, publishes, and sets parameters.
- :func:`dev_requirement` imports a test dependency of requirements/dev.txt: skipped where it
  is not installed, a failure on an environment ``make install`` set up.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable

import psutil
import yaml

from raspv_bringup.middleware import middleware_env
from raspv_bringup.supervisor import stop_with_parent   # the launcher stops its nodes when a test or bench dies
from raspv_common.extras import installed_extras
from raspv_common.ros_domains import lock_free_domain

PARAM_RETRY_S = 5.0       # a parameter request without an answer is sent again after this [s]

_domain_lock = None


CHROMIUM = "/usr/bin/chromium"          # Debian's chromium: the browser tests and `raspv bench qoe` drive it
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def dev_requirement(module: str, package: str | None = None) -> Any:
    """Import ``module`` of a test dependency (``package``, requirements/dev.txt or an extra). On
    an environment ``make install`` completed with the dev extra (``make test``; its stamp in
    ``sys.prefix``) a missing or broken one fails the test — the install checks they import, so
    its tests must run, not skip; elsewhere (the default install, a bare ``pip install -e .``)
    the test is skipped with the reason."""
    import importlib

    import pytest

    package = package or module.split(".")[0]
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if "dev" in (installed_extras() or ()):
            pytest.fail(f"{package} (requirements/dev.txt) does not import in this environment make install set up: "
                        f"{exc}; run make install EXTRAS=dev again", pytrace=False)
        pytest.skip(f"{package} (requirements/dev.txt) is not installed: make install EXTRAS=dev")


def claim_private_domain(low: int = 30, high: int = 160) -> int:
    """Lock and return an unused ROS domain id; also sets it (and the middleware defaults) in
    ``os.environ`` so rclpy in this process and every child uses it."""
    global _domain_lock
    i, _domain_lock = lock_free_domain(low, high)
    os.environ.update(middleware_env(os.environ, {"ROS_DOMAIN_ID": str(i)}))
    return i


class GraphStopped(AssertionError):
    """The graph ended while the test was waiting for it."""


class RunningGraph:
    """``raspv launch`` of a graph in a subprocess (its own process group)."""

    def __init__(self, spec: dict | str | Path, workdir: Path, overrides: list[str] | None = None,
                 env: dict[str, str] | None = None) -> None:
        if isinstance(spec, dict):
            path = workdir / f"graph-{int(time.time() * 1000) % 10**8}.yaml"
            path.write_text(yaml.safe_dump(spec, sort_keys=False))
        else:
            path = Path(spec)
        self.path = path
        self.log_path = workdir / (path.stem + ".log")
        self._log = open(self.log_path, "w")
        cmd = [sys.executable, "-m", "raspv_bringup.cli", "launch", str(path), *(overrides or [])]
        # node logs (the launcher's and rcl's) stay with the test's files, not in ~/.ros/log
        full_env = {**os.environ, "ROS_LOG_DIR": str(workdir / "ros_log"), **(env or {})}
        self.proc = subprocess.Popen(cmd, stdout=self._log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                     env=full_env, start_new_session=True, preexec_fn=stop_with_parent)
        self._children: set[int] = set()
        self.returncode: int | None = None

    @property
    def output(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors="replace")

    def spv_display(self) -> tuple[int, int] | None:
        """(display frames shown, dropped) from the spv node's exit line — its own count, unlike a
        subscriber's, which misses frames when its process is starved; the busiest spv process of
        the run (a warm spare reports too). None before the node stopped."""
        found = [(int(a), int(b)) for a, b in re.findall(r"spv: (\d+) display frames, (\d+) dropped", self.output)]
        return max(found) if found else None

    def cpu_by_kind(self) -> dict[str, tuple[int, float]]:
        """{node kind: (pid, CPU seconds so far)} of the graph's node processes (of a kind with a warm
        spare waiting, the older process: the one running the node)."""
        from raspv_bringup.registry import NODES

        module_kind = {spec.module: kind for kind, spec in NODES.items()}
        out, started = {}, {}
        try:
            children = psutil.Process(self.proc.pid).children(recursive=True)
        except psutil.Error:
            return out
        for p in children:
            try:
                cmd = p.cmdline()
                t = p.cpu_times()
                created = p.create_time()
            except psutil.Error:
                continue
            kinds = [module_kind[a] for a in cmd if a in module_kind]   # python -m [node_entry] MODULE
            if kinds and created < started.get(kinds[0], float("inf")):
                out[kinds[0]], started[kinds[0]] = (p.pid, t.user + t.system), created
        return out

    @staticmethod
    def cpu_share(before: dict[str, tuple[int, float]], after: dict[str, tuple[int, float]], wall_s: float) -> str:
        """"kind N %, …": each node's CPU between two :meth:`cpu_by_kind` calls, in % of one core."""
        return ", ".join(f"{kind} {100 * (t1 - before[kind][1]) / wall_s:.0f} %" for kind, (pid, t1) in sorted(after.items())
                         if kind in before and before[kind][0] == pid)

    @staticmethod
    def machine_ticks() -> tuple[int, int, int]:
        """(busy, stolen, total) CPU ticks of the machine so far (/proc/stat; zeros elsewhere):
        stolen time is the hypervisor running other guests, which no priority here can help."""
        try:
            fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
        except (OSError, ValueError):
            return 0, 0, 0
        idle = fields[3] + fields[4]
        steal = fields[7] if len(fields) > 7 else 0
        return sum(fields[:8]) - idle - steal, steal, sum(fields[:8])

    @staticmethod
    def machine_share(before: tuple[int, int, int], after: tuple[int, int, int]) -> str:
        """"machine busy N %, stolen M %" between two :meth:`machine_ticks` calls."""
        total = after[2] - before[2]
        if total <= 0:
            return "machine load unknown"
        return (f"machine busy {100 * (after[0] - before[0]) / total:.0f} %, "
                f"stolen by the hypervisor {100 * (after[1] - before[1]) / total:.1f} %")

    def _remember_children(self) -> None:
        try:
            self._children |= {c.pid for c in psutil.Process(self.proc.pid).children(recursive=True)}
        except psutil.Error:
            pass

    def running(self) -> bool:
        self._remember_children()
        return self.proc.poll() is None

    def wait_for_output(self, pattern: str, timeout: float = 30.0) -> re.Match:
        """Wait until the launcher's output matches ``pattern`` (regex)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            m = re.search(pattern, self.output)
            if m:
                return m
            if not self.running():
                raise GraphStopped(f"graph ended (code {self.proc.returncode}) before {pattern!r}:\n{self.output[-3000:]}")
            time.sleep(0.1)
        raise TimeoutError(f"{pattern!r} not in the graph output after {timeout:.0f} s:\n{self.output[-3000:]}")

    def wait_for_lines(self, pattern: str, count: int, timeout: float = 120.0) -> None:
        """Wait until ``count`` lines of the launcher's output match ``pattern`` (regex, multiline)."""
        deadline = time.monotonic() + timeout
        while len(re.findall(pattern, self.output, re.M)) < count:
            if not self.running():
                raise GraphStopped(f"graph ended (code {self.proc.returncode}) before {count} x {pattern!r}:\n"
                                   f"{self.output[-3000:]}")
            if time.monotonic() > deadline:
                raise TimeoutError(f"{count} lines matching {pattern!r} not seen within {timeout:.0f} s:\n"
                                   f"{self.output[-3000:]}")
            time.sleep(0.1)

    def pid_of(self, name: str) -> int:
        """The pid of node ``name``'s newest process (started or restarted), from the launcher's lines."""
        found = re.findall(rf"{name} \(\w+, pid (\d+)\)|node '{name}' ended .*?pid (\d+)\)", self.output)
        if not found:
            raise RuntimeError(f"no process of node {name!r} in the launcher's output")
        return int([a or b for a, b in found][-1])

    def stop(self, sig: int = signal.SIGINT, timeout: float = 30.0) -> int:
        """Signal the launcher, wait for it, and check every node process is gone."""
        if self.returncode is not None:
            return self.returncode
        self._remember_children()
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
                raise AssertionError(f"launcher did not stop within {timeout:.0f} s:\n{self.output[-3000:]}")
        self.returncode = self.proc.returncode
        self._log.close()
        leftovers = [p for p in self._children if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]
        for pid in leftovers:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if leftovers:
            raise AssertionError(f"processes left behind after the graph stopped: {leftovers}")
        return self.returncode


class Collector:
    """Messages received on one topic (thread-safe)."""

    def __init__(self) -> None:
        self.messages: list[Any] = []
        self.stamps: list[float] = []
        self._cond = threading.Condition()

    def _add(self, msg: Any) -> None:
        with self._cond:
            self.messages.append(msg)
            self.stamps.append(time.monotonic())
            self._cond.notify_all()

    def wait(self, count: int = 1, timeout: float = 30.0, predicate: Callable[[Any], bool] | None = None) -> list[Any]:
        """Block until ``count`` messages (matching ``predicate``) arrived; return them."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                got = [m for m in self.messages if predicate is None or predicate(m)]
                if len(got) >= count:
                    return got[:count]
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"{len(got)} of {count} messages after {timeout:.0f} s")
                self._cond.wait(min(left, 0.2))


def _wait_for_match(count: Callable[[], int], wanted: int, failure: str, timeout: float) -> None:
    """Poll ``count()`` (matched publishers or subscriptions) until it reaches ``wanted``."""
    deadline = time.monotonic() + timeout
    while count() < wanted:
        if time.monotonic() > deadline:
            raise TimeoutError(f"{failure} within {timeout:.0f} s")
        time.sleep(0.05)


class Probe:
    """An rclpy node spinning in a background thread of the test process (on ``domain_id``;
    None: the process's ROS_DOMAIN_ID)."""

    def __init__(self, name: str = "test_probe", domain_id: int | None = None) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self._rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context, args=["probe", "--ros-args", "--disable-rosout-logs"], domain_id=domain_id)
        self.node = rclpy.create_node(f"{name}_{os.getpid()}", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._closing = False
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()
        self._publishers: list[Any] = []
        self._collectors: list[Collector] = []

    def release(self) -> None:
        """Destroy the publishers and subscriptions made since the last call (the end of a test),
        so a latched message or a subscription of one test does not reach into the next."""
        for pub in self._publishers:
            self.node.destroy_publisher(pub)
        for col in self._collectors:
            self.node.destroy_subscription(col.subscription)
        self._publishers, self._collectors = [], []

    def _spin(self) -> None:
        """Spin until :meth:`close`. An error inside one spin (a subscription destroyed by
        :meth:`release` while the executor waits on it) is reported and spinning goes on: one
        escaping ``executor.spin()`` used to end this thread silently, and every later test of the
        session then timed out waiting for messages."""
        while not self._closing and self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=0.1)
            except Exception as exc:
                if self._closing or not self.context.ok():
                    break
                print(f"probe: {type(exc).__name__} while spinning: {exc}; spinning on", file=sys.stderr, flush=True)

    def close(self) -> None:
        self._closing = True
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=3.0)

    def subscribe(self, topic: str, msg_type: type, qos: Any = None, wait_for_publishers: int = 0,
                  timeout: float = 30.0) -> Collector:
        """Start collecting ``topic``; by default with a QoS that matches any publisher
        (best-effort reliability is compatible with reliable publishers). Optionally wait until
        ``wait_for_publishers`` publishers matched, for a test that counts what one burst delivers."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        if qos is None:
            qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
        col = Collector()
        col.subscription = self.node.create_subscription(msg_type, topic, col._add, qos)
        self._collectors.append(col)
        _wait_for_match(col.subscription.get_publisher_count, wait_for_publishers,
                        f"no publisher matched {topic}", timeout)
        return col

    def unsubscribe(self, col: Collector) -> None:
        if col in self._collectors:
            self._collectors.remove(col)
            self.node.destroy_subscription(col.subscription)

    def wait_for_message(self, topic: str, msg_type: type, timeout: float = 30.0, qos: Any = None,
                         predicate: Callable[[Any], bool] | None = None) -> Any:
        col = self.subscribe(topic, msg_type, qos)
        try:
            return col.wait(1, timeout, predicate)[0]
        finally:
            self.unsubscribe(col)

    def collect(self, topic: str, msg_type: type, count: int, timeout: float = 30.0, qos: Any = None) -> list[Any]:
        col = self.subscribe(topic, msg_type, qos)
        try:
            return col.wait(count, timeout)
        finally:
            self.unsubscribe(col)

    def publisher(self, topic: str, msg_type: type, qos: Any = None, wait_for_subscribers: int = 0,
                  timeout: float = 30.0):
        """A publisher; optionally wait until ``wait_for_subscribers`` subscriptions matched."""
        from raspv_common.qos import COMMAND_QOS

        pub = self.node.create_publisher(msg_type, topic, qos or COMMAND_QOS)
        self._publishers.append(pub)
        _wait_for_match(pub.get_subscription_count, wait_for_subscribers, f"no subscriber matched {topic}", timeout)
        return pub

    def _param_call(self, target: str, call: Callable, timeout: float) -> Any:
        from raspv_common.param_client import ParamClient

        client = ParamClient(self.node, target)
        try:
            ok, answer = client.ask_until_answered(lambda done: call(client, done), timeout, PARAM_RETRY_S)
        finally:
            client.destroy()
        if not ok:
            raise TimeoutError(answer)
        return answer

    def set_params(self, target: str, values: dict[str, Any], timeout: float = 30.0) -> list[tuple[str, bool, str]]:
        """Set parameters of node ``target``; returns [(name, successful, reason)]."""
        return self._param_call(target, lambda c, done: c.set_async(values, done), timeout)

    def get_params(self, target: str, names: list[str], timeout: float = 30.0) -> dict[str, Any]:
        return self._param_call(target, lambda c, done: c.get_async(names, done), timeout)
