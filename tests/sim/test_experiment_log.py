"""Experiment logs: written line by line (a killed run loses nothing), summarised and plotted."""
from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap

import pytest

from raspv_sim.experiment_log import TRAJECTORY_FIELDS, read_events, read_trajectory, summarize_run
from raspv_sim.sim_cli import main as sim_cli

RUN = textwrap.dedent("""
    import sys
    from raspv_sim.simulator import SimConfig, Simulation
    sim = Simulation("apartment", SimConfig(width=16, height=12, renderer="tiny"))
    log = sim.start_log(sys.argv[1], rate=10.0)
    print(log.dir, flush=True)
    # walk down the corridor into the living room, turn right and on into the TV cabinet
    for i in range(100000):
        turn = -1.2 if 130 <= i < 155 else 0.0
        report = sim.step(0.05, 1.0, turn)
        if report.collisions:
            print("collided", report.collisions[0].name, flush=True)
        if i == 260:
            print("waiting to be killed", flush=True)
""")


def test_a_killed_run_keeps_its_log_and_can_be_summarised_and_plotted(tmp_path):
    proc = subprocess.Popen([sys.executable, "-c", RUN, str(tmp_path)], stdout=subprocess.PIPE, text=True)
    try:
        run_dir = proc.stdout.readline().strip()
        lines = []
        for line in proc.stdout:
            lines.append(line.strip())
            if line.startswith("waiting"):
                break
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    assert "collided tv_cabinet" in lines
    traj = read_trajectory(run_dir)
    assert list(traj) == list(TRAJECTORY_FIELDS)
    assert len(traj["t"]) >= 130                  # 10 Hz over ≥ 13 s of sim time
    assert traj["t"][1] - traj["t"][0] == pytest.approx(0.1, abs=1e-6)
    assert traj["x"][-1] > 6.0 and traj["path_length"][-1] > 8.0
    events = read_events(run_dir)
    assert [(e["event"], e["name"], e["class"], e["count"]) for e in events] == [("collision", "tv_cabinet", "cabinet", 1)]
    summary = summarize_run(run_dir)
    assert summary["collisions"] == 1 and summary["collisions_by_class"] == {"cabinet": 1}
    assert summary["goals_missed"] == ["sofa"]
    assert sim_cli(["plot", run_dir]) == 0
    png = tmp_path / run_dir.split("/")[-1] / "trajectory.png"
    assert png.stat().st_size > 20_000
    assert json.loads((png.parent / "summary.json").read_text())["samples"] == len(traj["t"])


def test_a_finished_run_writes_summary_and_plot(tmp_path):
    from raspv_sim.simulator import SimConfig, Simulation

    with Simulation("apartment", SimConfig(width=16, height=12, renderer="tiny")) as sim:
        log = sim.start_log(tmp_path, rate=5.0)
        sim.avatar.teleport(10.6, 2.0, 1.5707963)   # north along the gap between table and sofa
        for _ in range(40):
            sim.step(0.05, 1.0, 0.0)
        summary, png = sim.finish_log()
    assert summary["goals_reached"] == {"sofa": pytest.approx(1.3, abs=0.06)}
    assert summary["samples"] == len(read_trajectory(log.dir)["t"]) and png.is_file()
    assert [e["event"] for e in read_events(log.dir)] == ["goal"]
