"""What the wearer saw, recorded (issue 21): a virtual patient's session with a bag per trial; the
trial record's display share and `raspv bag info` on the real recording say the same — every frame
in the condition's own representation (a headless spv node never falls back)."""
from __future__ import annotations

import subprocess
import sys

import pytest
import yaml

from raspv_experiments.protocol import EXPERIMENTS_DIR
from raspv_experiments.session import read_jsonl

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_trial_record_and_bag_info_agree(tmp_path):
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "hallway.yaml").write_text((EXPERIMENTS_DIR / "worlds" / "hallway.yaml").read_text())
    doc = yaml.safe_load((EXPERIMENTS_DIR / "example.yaml").read_text())
    doc.update(name="shown", conditions={"depth": {"spv": {"mode": "depth"}}}, record={"bag": True})
    doc["design"]["repetitions"] = 1
    doc["tasks"]["hallway"]["time_limit"] = 3
    (tmp_path / "shown.yaml").write_text(yaml.safe_dump(doc))
    run = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "experiment", "run", str(tmp_path / "shown.yaml"),
                          "--subject", "scripted", "--out", str(tmp_path / "s")], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    (record,) = read_jsonl(tmp_path / "s" / "shown" / "scripted-navigate-1" / "trials.jsonl")
    d = record["display"]
    assert (d["frames"], d["own_frames"], d["own_share"], d["fallbacks"]) == (30, 30, 1.0, {})
    assert d["expected_mode"] == "depth" and d["device"] == "argus_ii" and d["phosphenes_shown"] == 60
    info = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "bag", "info", record["bag"]],
                          capture_output=True, text=True, timeout=120)
    assert info.returncode == 0, info.stderr
    shown = next(line for line in info.stdout.splitlines() if line.startswith("shown:"))
    assert "100.0 % of" in shown and "frames in depth" in shown and "instead" not in shown, shown


def test_ctrl_c_is_a_quit_the_session_can_resume_from(tmp_path):
    import os
    import signal
    import time

    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "hallway.yaml").write_text((EXPERIMENTS_DIR / "worlds" / "hallway.yaml").read_text())
    doc = yaml.safe_load((EXPERIMENTS_DIR / "example.yaml").read_text())
    doc.update(name="stop")
    doc["tasks"]["hallway"]["time_limit"] = 3
    (tmp_path / "stop.yaml").write_text(yaml.safe_dump(doc))
    proc = subprocess.Popen([sys.executable, "-m", "raspv_bringup.cli", "experiment", "run", str(tmp_path / "stop.yaml"),
                             "--subject", "scripted", "--out", str(tmp_path / "s")], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)
    session = tmp_path / "s" / "stop" / "scripted-navigate-1"
    try:
        deadline = time.monotonic() + 240
        while not read_jsonl(session / "trials.jsonl"):
            assert proc.poll() is None and time.monotonic() < deadline, "no trial finished"
            time.sleep(0.2)
        os.kill(proc.pid, signal.SIGINT)                    # the experimenter's Ctrl-C
        out, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, out[-2000:]
    events = read_jsonl(session / "events.jsonl")
    assert events[-1]["event"] == "quit" and events[-1]["by"] == "signal"
    assert "stopped" in out and "| finished" not in out and "--resume" in out
