"""The recorder and the graph (issue 36): `raspv bag record` started from a terminal runs its
work in a session of its own, lowered to `--nice` once recording (with autogroup, Linux shares
the CPU between sessions first, so a nice value inside the terminal's session did not yield to
the graph's nodes), and a recorder that falls behind never loses messages silently: its
subscriptions hold RECORD_DEPTH messages, and what they lose all the same is counted from the
publishers' sequence numbers and reported. Real recorder, a test publisher; the recorder is
held with SIGSTOP while a burst is published."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time

import psutil
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from raspv_bags.reader import BagReader
from raspv_common.thread_priority import session_nice

pytestmark = pytest.mark.integration

BURST = 900
NICE = 7
TOPIC = "/test/burst"


def _wait_line(proc, pattern: str, timeout: float = 60.0) -> str:
    deadline = time.monotonic() + timeout
    for line in proc.stdout:
        if re.search(pattern, line):
            return line
        assert time.monotonic() < deadline, f"no line matching {pattern!r}"
    raise AssertionError(f"the recorder ended before a line matching {pattern!r}")


def test_the_recorder_works_in_a_session_of_its_own_and_counts_what_it_lost(probe, tmp_path):
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=BURST, reliability=ReliabilityPolicy.RELIABLE)
    pub = probe.node.create_publisher(String, TOPIC, qos)
    pub.publish(String(data="0"))
    rec = subprocess.Popen([sys.executable, "-m", "raspv_bringup.cli", "bag", "record", TOPIC, "-o",
                            str(tmp_path / "bag"), "--flush-interval", "0.2", "--nice", str(NICE)],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        _wait_line(rec, r"\+ /test/burst")
        deadline = time.monotonic() + 60
        while pub.get_subscription_count() < 1:          # the recorder's subscription matched
            assert time.monotonic() < deadline, "the recorder never subscribed"
            time.sleep(0.05)
        pub.publish(String(data="1"))                    # (message 0 was before it: not recorded)
        _wait_line(rec, r"^recording .*/test/burst 1\b")  # its status line (every 5 s): taken
        workers = psutil.Process(rec.pid).children()
        assert len(workers) == 1, "the recording is not in a process of its own"
        worker = workers[0]
        assert os.getsid(worker.pid) == worker.pid and worker.nice() >= NICE
        with open(f"/proc/{worker.pid}/autogroup") as f:
            group = f.read()
        if session_nice() is not None:                   # a kernel with a readable autogroup
            assert f"nice {NICE}" in group, group
        worker.suspend()                                 # the recorder falls behind: a burst meanwhile
        for k in range(2, BURST):
            pub.publish(String(data=str(k)))
        worker.resume()
        deadline = time.monotonic() + 60
        while True:                                      # its status line, every 5 s: all taken or lost
            line = _wait_line(rec, r"^recording ")
            taken = int(re.search(r"/test/burst (\d+)", line).group(1))
            lost = int(m.group(1)) if (m := re.search(r"LOST (\d+)", line)) else 0
            if taken + lost >= BURST - 1 or time.monotonic() > deadline:
                break
        rec.send_signal(signal.SIGINT)
        summary = rec.communicate(timeout=60)[0]
    finally:
        if rec.poll() is None:
            rec.kill()
            rec.wait()
        probe.node.destroy_publisher(pub)
    assert rec.returncode == 0, summary
    with BagReader(tmp_path / "bag") as r:
        got = [int(r.decode(m).data) for m in r.messages([TOPIC])]
    assert got[0] == 1 and got[-1] == BURST - 1 and len(got) == taken, (got[:3], got[-3:], summary)
    assert taken + lost == BURST - 1, (taken, lost, summary)      # nothing lost without saying so
    if lost:
        assert f"({lost} lost)" in summary and f"{lost} messages were published but lost" in summary, summary
    print(f"{taken} recorded, {lost} counted lost of {BURST}")
