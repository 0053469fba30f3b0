"""Session records survive kills (one fsync'ed line per trial), resume at the next trial, and the
experimenter's keys and trial ends are state machines without I/O."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from raspv_experiments.design import plan_session
from raspv_experiments.protocol import EXPERIMENTS_DIR, load_protocol
from raspv_experiments.session import SessionError, SessionFolder, append_jsonl, read_jsonl
from raspv_experiments.session_control import ExperimenterControl, TrialMonitor, ViewState, elapsed_and_eta, status_line
from raspv_experiments.subject_ability import subject_ability
from raspv_experiments.session_runner import RunOptions, parse_subject, session_graph

EXAMPLE = EXPERIMENTS_DIR / "example.yaml"


def test_records_are_on_disk_when_the_writer_is_killed(tmp_path):
    path = tmp_path / "trials.jsonl"
    code = textwrap.dedent(f"""
        import os, signal
        from raspv_experiments.session import append_jsonl
        from pathlib import Path
        for i in range(3):
            append_jsonl(Path({str(path)!r}), {{"index": i + 1, "status": "completed"}})
        with open({str(path)!r}, "a") as f:
            f.write('{{"index": 4, "stat')          # a line cut by the kill
            f.flush()
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    proc = subprocess.run([sys.executable, "-c", code])
    assert proc.returncode == -9
    assert [r["index"] for r in read_jsonl(path)] == [1, 2, 3]
    append_jsonl(path, {"index": 5, "value": float("nan")})       # NaN metrics are written as NaN
    assert [r["index"] for r in read_jsonl(path)] == [1, 2, 3, 5]


def test_session_folder_resume_and_attempts(tmp_path):
    protocol = load_protocol(EXAMPLE)
    plan = plan_session(protocol, "S01")
    folder = SessionFolder.for_subject(tmp_path, protocol, "S01")
    assert folder.root == tmp_path / "example" / "S01" and not folder.exists()
    folder.create(protocol, "S01", plan, {"subject_kind": "person"})
    info = json.loads(folder.info_path.read_text())
    assert info["protocol_sha256"] == protocol.sha256 and len(info["plan"]) == 6
    assert "raspv" in info["software"] and info["graph"][1]["kind"] == "spv"
    assert (folder.root / "protocol.yaml").read_text() == EXAMPLE.read_text()
    folder.record({"index": 1, "status": "completed"})
    folder.record({"index": 2, "status": "repeated"})
    folder.record({"index": 2, "status": "skipped"})
    folder.record({"index": 3, "status": "interrupted"})
    assert folder.done() == {1, 2}
    trial = plan[2]
    (folder.root / "trials" / f"{trial.slug}-a1").mkdir()          # an attempt a kill cut short
    assert folder.attempt_dir(trial) == (f"{trial.slug}-a2", 2)
    assert folder.check_resumable(protocol, "S01")["subject"] == "S01"
    with pytest.raises(SessionError, match="not 'S02'"):
        folder.check_resumable(protocol, "S01".replace("1", "2"))
    changed = load_protocol(EXAMPLE)
    changed.text += "\n# edited\n"
    with pytest.raises(SessionError, match="changed since this session started"):
        folder.check_resumable(changed, "S01")


def test_experimenter_keys():
    c = ExperimenterControl()
    c.key("p")
    assert c.paused and "paused" in c.message
    c.key("p")
    assert not c.paused
    c.key("r")
    assert c.take_request() == "repeat" and c.take_request() is None
    c.key("S")
    assert c.take_request() == "skip"
    c.key("enter")
    assert c.take_start() and not c.take_start()
    c.key("x")
    assert "does nothing" in c.message


def test_trial_monitor_ends_at_goal_time_limit_or_abort():
    m = TrialMonitor(5.0, 0.0, 0.5, time_limit=10.0, start_t=100.0, t=100.0)
    assert m.update(101.0, 0.0, 0.0) is None and m.elapsed == 1.0
    assert m.update(102.0, 4.6, 0.1) == "goal"
    m = TrialMonitor(5.0, 0.0, 0.5, 10.0, 100.0, 100.0)
    assert m.update(99.0) is None and m.elapsed == 0.0             # the clock never goes back
    assert m.update(110.0, 0.0, 0.0) == "time_limit"
    # a pose from before the reset (the last trial ended in this goal) does not end the new trial
    m = TrialMonitor(5.0, 0.0, 0.5, 10.0, 100.0, 100.0, start_x=0.0, start_y=0.0)
    assert m.update(100.1, 5.0, 0.0) is None and not m.armed
    assert m.update(100.2, 0.1, 0.0) is None and m.armed
    assert m.update(103.0, 5.0, 0.1) == "goal"
    m = TrialMonitor(5.0, 0.0, 0.5, 10.0, 100.0, 100.0)
    m.abort()
    assert m.update(101.0, 5.0, 0.0) == "aborted"


def test_status_line():
    v = ViewState(done=2, total=6, index=3, label="depth / hallway / rep 3", phase="running", elapsed=12.34,
                  time_limit=40, collisions=1, last_hit="box:crate")
    line = status_line(v, 200)
    assert line.startswith("[#######.............] 2/6 | trial 3: depth / hallway / rep 3 | running |  12.3/40 s")
    assert "1 collision (last: box:crate)" in line
    assert len(status_line(v, 30)) == 30
    v.started, v.now, v.done_before = 100.0, 160.0, 1             # resumed at 1 done; 1 more in 60 s
    assert "2/6 elapsed 1:00, ETA 4:00 |" in status_line(v, 200)
    assert elapsed_and_eta(0, 5, 30.0) == "elapsed 0:30" and elapsed_and_eta(5, 5, 4000) == "elapsed 1:06:40"


def test_subject_ids():
    assert parse_subject("S07") == ("S07", None, 7)
    assert parse_subject("scripted") == ("scripted-navigate-1", "navigate", 1)           # the default virtual patient
    assert parse_subject("scripted:follow_path") == ("scripted-follow_path-1", "follow_path", 1)
    assert parse_subject("scripted:wander_avoid:4") == ("scripted-wander_avoid-4", "wander_avoid", 4)
    for bad, msg in [("scripted:fly", "unknown policy"), ("scripted:follow_path:x", "must be a number"),
                     ("a b", "without spaces"), ("anna", "has no number")]:
        with pytest.raises(ValueError, match=msg):
            parse_subject(bad)


def test_session_graph_for_people_and_scripted_subjects(tmp_path):
    protocol = load_protocol(EXAMPLE)
    person = session_graph(protocol, "office", RunOptions(tmp_path, "S01"), 1)
    assert [n.kind for n in person.nodes] == ["sim", "spv", "bridge"]
    assert person.node("sim").params["world"] == "office" and "step_mode" not in person.node("sim").params
    scripted = session_graph(protocol, "office", RunOptions(tmp_path, "scripted-follow_path-2", "follow_path"), 2)
    assert [n.kind for n in scripted.nodes] == ["sim", "spv", "subject"]           # no bridge: headless
    assert scripted.node("sim").params["step_mode"] == "lockstep"
    assert scripted.node("spv").params["headless"] and scripted.node("spv").params["use_sim_time"]
    assert scripted.node("subject").params == {**subject_ability(2), "policy": "follow_path", "seed": 2,
                                               "use_sim_time": True}               # virtual subject 2's ability
    assert scripted.node("sim").params["lockstep_hold"] and "lockstep_participants" not in scripted.node("sim").params
    baked = session_graph(protocol, "office", RunOptions(tmp_path, "scripted-navigate-2", "navigate"), 2, "depth")
    assert baked.node("spv").params["mode"] == "depth"                     # exact runs: the condition in the graph
    assert protocol.graph.node("sim").params.get("world") is None                    # the protocol is untouched
    office = session_graph(load_protocol(EXAMPLE.parent / "office_navigation.yaml"), "office",
                           RunOptions(tmp_path, "scripted-navigate-2", "navigate"), 2, "downsampling")
    assert office.node("planner").params["lockstep"] and office.node("sim").params["lockstep_participants"] == ["planner"]
    assert office.node("scene").params["lockstep"]         # each depth frame with the camera pose of its stamp
