"""A session that stops in a sweep's worker (a stalled simulation clock, a session that cannot
resume) is one line and a --resume hint from the driver, not a traceback; and the stall watch
does not count time the runner itself was suspended (a paused or starved machine)."""
from __future__ import annotations

import json
import subprocess
import sys

import yaml

from raspv_experiments.protocol import EXPERIMENTS_DIR
from raspv_experiments.session_control import ClockWatch


def test_the_clock_watch_counts_only_what_it_watched():
    w = ClockWatch(stall_s=60.0, max_gap_s=1.0)
    assert not w.update(None, 0.0)
    t = 0.0
    for _ in range(5900):                        # the clock stands, polled every 10 ms for 59 s
        t += 0.01
        assert not w.update(None, t)
    assert not w.update(None, t + 300.0)         # the runner itself was suspended 5 min: counts 1 s
    t += 300.0
    for _ in range(100):                         # ... then 1 s more of standing: stuck
        t += 0.01
        stuck = w.update(None, t)
    assert stuck and 60.0 < w.still_s < 61.1
    assert not w.update(12.5, t + 0.01) and w.still_s == 0.0     # the clock moved: watched again from 0
    w.still_s = 59.9
    w.reset()                                                     # the experimenter paused the world
    assert w.still_s == 0.0 and not w.update(12.5, t + 30.0)


def test_a_session_that_stops_in_a_worker_is_one_line(tmp_path):
    """A worker's SessionError (here: --resume of a session whose protocol changed, raised where the
    stalled clock's is, in SessionRunner.run) reaches the driver as a line naming --resume."""
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "hallway.yaml").write_text((EXPERIMENTS_DIR / "worlds" / "hallway.yaml").read_text())
    (tmp_path / "short.yaml").write_text((EXPERIMENTS_DIR / "example.yaml").read_text())
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump({
        "name": "stops", "protocol": "short.yaml", "policy": "wander_avoid", "subjects": 1,
        "factors": {"spv.mode": ["depth"]}}))
    session = tmp_path / "out" / "sessions" / "stops" / "scripted-wander_avoid-1"
    session.mkdir(parents=True)
    (session / "session.json").write_text(json.dumps({"protocol": "stops", "subject": "scripted-wander_avoid-1",
                                                      "protocol_sha256": "0" * 64}))
    run = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "experiment", "sweep", str(tmp_path / "sweep.yaml"),
                          "--out", str(tmp_path / "out"), "--resume", "--workers", "1"],
                         capture_output=True, text=True, timeout=180)
    assert run.returncode == 1, run.stderr
    assert "Traceback" not in run.stderr + run.stdout
    assert "scripted-wander_avoid-1: stopped after 0 trials:" in run.stdout
    line = [x for x in run.stderr.splitlines() if x.startswith("sweep stopped:")]
    assert line and "1 of 1 sessions did not finish" in line[0] and "changed since this session started" in line[0]
    assert line[0].endswith(f"--resume --out {tmp_path / 'out'}")
