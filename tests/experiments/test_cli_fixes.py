"""The smaller defects of issue 23, each as a new user meets it: ``check NAME`` of a sweep, ``plan``
with a virtual subject, a copied protocol that keeps its original's name, ``--resume`` without a
session, a sweep's domain range, reports over two protocols, trial logs in time since their start."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest
import yaml

from raspv_experiments.protocol import EXPERIMENTS_DIR
from raspv_experiments.report import ReportError, build_report
from tests.experiments.test_report_stats import fake_session


def raspv(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "experiment", *args], capture_output=True,
                          text=True, timeout=180, cwd=cwd)


def test_check_plan_and_copied_names(tmp_path, write_protocol, example_doc):
    sweep = raspv("check", "office_modes_sweep")                    # a sweep by name, as protocols are
    assert sweep.returncode == 0 and "sweep of 3 virtual subjects" in sweep.stdout, sweep.stderr
    plan = raspv("plan", "example", "--subject", "scripted:navigate:2")
    assert plan.returncode == 0 and "downsampling / hallway" in plan.stdout.splitlines()[0], plan.stderr
    copied = write_protocol(example_doc, "my_study.yaml")            # cp example.yaml my_study.yaml
    check = raspv("check", str(copied))
    assert check.returncode == 0
    assert "name: 'example' is not the file's name ('my_study')" in check.stderr and "<out>/example/" in check.stderr


def test_resume_without_a_session_and_sweep_domains(tmp_path, write_protocol, example_doc):
    proto = write_protocol(example_doc, "example.yaml")
    run = raspv("run", str(proto), "--subject", "S01", "--out", str(tmp_path / "none"), "--resume")
    assert run.returncode == 2 and "no session to resume" in run.stderr and "Traceback" not in run.stderr
    assert not (tmp_path / "none").exists() or not any((tmp_path / "none").rglob("session.json"))
    bad = raspv("sweep", "office_modes_sweep", "--domains", "200-100", "--out", str(tmp_path / "sw"))
    assert bad.returncode == 2 and "--domains 200-100: expected LOW-HIGH" in bad.stderr


def test_private_domains_stay_in_the_range():
    from raspv_experiments.domains import private_domain

    with private_domain(150, 153) as a, private_domain(150, 153) as b:
        assert {a, b} <= {150, 151, 152} and a != b


def test_reports_refuse_to_pool_protocols_unless_asked(tmp_path):
    fake_session(tmp_path / "a", "S01", {"depth": [12.0, 11.0], "grey": [25.0, 31.0]})
    fake_session(tmp_path / "b", "S01", {"depth": [14.0, 13.0], "grey": [29.0, 24.0]})
    for k, sha in (("a", "1" * 64), ("b", "2" * 64)):                 # the same name, two different files
        (tmp_path / k / "example" / "S01" / "session.json").write_text(
            json.dumps({"protocol": "example", "subject": "S01", "protocol_sha256": sha}))
    with pytest.raises(ReportError, match="2 different protocols: example .*--pool"):
        build_report([tmp_path / "a", tmp_path / "b"], tmp_path / "r")
    page = build_report([tmp_path / "a", tmp_path / "b"], tmp_path / "r", pool=True).read_text()
    assert "pools 2 protocols" in page and "example@11111111/S01" in page and "example@22222222/S01" in page


def test_trial_logs_count_time_from_their_start(tmp_path):
    from raspv_sim.experiment_log import read_events, read_trajectory, sim_time_at_start
    from raspv_sim.simulator import SimConfig, Simulation
    from raspv_sim.world_spec import GoalSpec

    with Simulation(EXPERIMENTS_DIR / "worlds" / "hallway.yaml", SimConfig(width=16, height=12, renderer="tiny")) as sim:
        for _ in range(30):
            sim.step(0.1)                                           # 3 s of an earlier trial
        sim.start_trial(1.0, 1.5, 0.0, (GoalSpec("ahead", (1.5, 1.5), 0.2),))
        log = sim.start_log(tmp_path, run_name="t")
        for _ in range(10):
            sim.step(0.1, 0.6, 0.0)
        summary, _ = sim.finish_log(plot=False)
    t = read_trajectory(log.dir)["t"]
    assert t[0] == 0.0 and t[-1] == pytest.approx(1.0) and summary["duration_s"] == pytest.approx(1.0)
    assert sim_time_at_start(log.dir) == pytest.approx(3.0)
    assert 0.0 < read_events(log.dir)[0]["t"] <= 1.0 and 0.0 < summary["goals_reached"]["ahead"] <= 1.0
