"""How the launcher runs node processes: quiet exits when interrupted while starting, warm spares,
and the terminal's one-line summaries of tracebacks (their full text stays in the node's log)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from raspv_bringup.node_output import TracebackSummariser
from raspv_bringup.supervisor import _die_with_parent

SLOW_IMPORT = """
import pathlib, time
pathlib.Path({marker!r}).write_text("importing")
time.sleep(60)

def main(argv):
    print("main ran", flush=True)
"""

# A C extension's module init interrupted by SIGINT: pybind11 reports an ImportError chained from
# the KeyboardInterrupt (seen with rclpy's _rclpy_pybind11: "ImportError: initialization failed")
EXTENSION_IMPORT = """
import pathlib, time
pathlib.Path({marker!r}).write_text("importing")
try:
    time.sleep(60)
except KeyboardInterrupt as exc:
    raise ImportError("initialization failed") from exc
"""

BROKEN_IMPORT = """
raise ImportError("initialization failed")
"""

FAST_NODE = """
import os

def main(argv):
    print("main", argv[1:], "spawned at", os.environ.get("RASPV_SPAWN_TIME"), flush=True)
"""

# A real node (run_node, rclpy) whose timer callback sees SIGINT's KeyboardInterrupt turned into
# pybind11's RuntimeError, as rclpy's take_message does when the interrupt lands inside a
# message's conversion to Python (the scene node's log at a stop, CI of 7 Dec) — or, with
# "real", a RuntimeError that no signal caused, which must still be a crash. The callback calls
# the process's Python SIGINT handler itself: the KeyboardInterrupt comes before rclpy's signal
# thread has shut the context down (in that CI run the context was still ok; raise_signal would
# let rclpy's handler win the race here and the case would pass without the fix).
CONVERSION_NODE = """
import signal, sys
from raspv_common.node import RaspvNode, run_node

class ConversionNode(RaspvNode):
    def __init__(self):
        super().__init__("conversion", [])
        self.create_timer(0.01, self.tick)

    def tick(self):
        if sys.argv[-1] == "real":
            raise RuntimeError("a real failure")
        try:
            signal.getsignal(signal.SIGINT)(signal.SIGINT, None)
        except KeyboardInterrupt:
            raise RuntimeError("Unable to convert call argument '0' to Python object") from None

def main(argv):
    run_node(ConversionNode, argv)
"""


def _entry(tmp_path: Path, module: str, *args: str, node_args: tuple[str, ...] = (), **kw) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    return subprocess.Popen([sys.executable, "-m", "raspv_bringup.node_entry", *args, module, *node_args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=_die_with_parent, **kw)


def _wait_for(path: Path, proc: subprocess.Popen, bound: float = 60.0) -> None:
    deadline = time.monotonic() + bound
    while not path.exists():
        assert proc.poll() is None, proc.communicate()[0]
        assert time.monotonic() < deadline, "the module never started importing"
        time.sleep(0.02)


def _interrupted_while_importing(tmp_path, name: str, source: str) -> tuple[int, str]:
    """Start node module ``name`` (``source``, which marks when its import began), SIGINT it
    then: (exit code, output)."""
    marker = tmp_path / "importing"
    (tmp_path / f"{name}.py").write_text(source.format(marker=str(marker)))
    proc = _entry(tmp_path, name)
    _wait_for(marker, proc)
    proc.send_signal(signal.SIGINT)
    out = proc.communicate(timeout=30)[0]
    return proc.returncode, out


def test_a_node_interrupted_while_importing_exits_quietly(tmp_path):
    code, out = _interrupted_while_importing(tmp_path, "slow_import_node", SLOW_IMPORT)
    assert code == 130 and "Traceback" not in out and "KeyboardInterrupt" not in out, out


def test_an_import_error_caused_by_the_interrupt_exits_quietly_and_a_real_one_shows(tmp_path):
    code, out = _interrupted_while_importing(tmp_path, "extension_node", EXTENSION_IMPORT)
    assert code == 130 and "Traceback" not in out and "ImportError" not in out, out
    (tmp_path / "broken_node.py").write_text(BROKEN_IMPORT)
    proc = _entry(tmp_path, "broken_node")
    out = proc.communicate(timeout=60)[0]
    assert proc.returncode == 1 and "Traceback" in out and "ImportError: initialization failed" in out, out


def test_a_sigint_before_the_interpreter_is_up_waits_and_exits_quietly(tmp_path):
    """The launcher starts nodes with SIGINT blocked: sent at once, it is not a 'Fatal Python
    error' in the interpreter's own start-up but a quiet exit once node_entry can take it."""
    (tmp_path / "fast_node.py").write_text(FAST_NODE)
    for _ in range(3):
        proc = _entry(tmp_path, "fast_node")
        proc.send_signal(signal.SIGINT)
        out = proc.communicate(timeout=60)[0]
        assert proc.returncode == 130 and "Fatal Python error" not in out and "Traceback" not in out, out


def test_a_sigint_inside_a_message_conversion_is_a_clean_stop_and_a_real_error_is_not(tmp_path, ros_domain):
    (tmp_path / "conversion_node.py").write_text(CONVERSION_NODE)
    proc = _entry(tmp_path, "conversion_node", node_args=("interrupted",))
    out = proc.communicate(timeout=60)[0]
    assert proc.returncode == 0 and "Traceback" not in out, out
    proc = _entry(tmp_path, "conversion_node", node_args=("real",))
    out = proc.communicate(timeout=60)[0]
    assert proc.returncode == 1 and "RuntimeError: a real failure" in out, out


def test_a_warm_spare_waits_then_runs_the_node_or_leaves_when_not_needed(tmp_path):
    (tmp_path / "fast_node.py").write_text(FAST_NODE)
    spare = _entry(tmp_path, "fast_node", "--spare", stdin=subprocess.PIPE)
    spare.stdin.write("1234.5\n")
    spare.stdin.close()
    out = spare.stdout.read()
    spare.wait(timeout=60)
    assert spare.returncode == 0 and "main [] spawned at 1234.5" in out, out
    unused = _entry(tmp_path, "fast_node", "--spare", stdin=subprocess.PIPE)
    unused.stdin.close()                                       # the launcher no longer needs it
    out = unused.stdout.read()
    unused.wait(timeout=60)
    assert unused.returncode == 0 and "main" not in out, out


def test_tracebacks_become_one_line_and_expected_ones_none():
    lines = ["starting", "Traceback (most recent call last):", '  File "x.py", line 1, in <module>',
             "    import y", "    ^^^^^^^^", "ValueError: first", "",
             "During handling of the above exception, another exception occurred:", "",
             "Traceback (most recent call last):", '  File "x.py", line 3, in <module>', "KeyError: 'k'",
             "after", "Exception ignored in: <function Future.__del__ at 0x1>", "Traceback (most recent call last):",
             '  File "t.py", line 56, in __del__', "AttributeError: 'Task' object has no attribute '_exception'",
             "Traceback (most recent call last):", '  File "n.py", line 9', "KeyboardInterrupt", "end"]
    s = TracebackSummariser("/logs/spv.log")
    shown = [x for x in (s.feed(line) for line in lines) if x is not None]
    assert shown == ["starting", "raised ValueError: first (full traceback in /logs/spv.log)",
                     "raised KeyError: 'k' (full traceback in /logs/spv.log)", "after",
                     "raised AttributeError: 'Task' object has no attribute '_exception' (full traceback in /logs/spv.log)",
                     "raised KeyboardInterrupt (full traceback in /logs/spv.log)", "end"]
    quiet = TracebackSummariser("/logs/spv.log", quiet=lambda line, ignored: ignored or line == "KeyboardInterrupt")
    shown = [x for x in (quiet.feed(line) for line in lines) if x is not None]
    assert "raised KeyError: 'k' (full traceback in /logs/spv.log)" in shown
    assert not any("AttributeError" in x or "KeyboardInterrupt" in x for x in shown)
    cut = TracebackSummariser("/logs/a.log")
    cut.feed("Traceback (most recent call last):")
    cut.feed('  File "x.py", line 1')
    assert "ended early" in cut.flush()
