"""Touch in the graph: the `subject` node feels a bump (/sim/collisions) with the frame of its step,
as quick_trial's subject does, so a lockstep graph trial and a quick trial of the same virtual
subject and seed bump alike and walk the same path after the bump. Before, the graph's subject
never felt it: after the bump it kept walking into the wall (0.38 m from the quick trial's path
1.6 s later) where the quick one stepped back. Virtual subject 3 at 30 phosphenes bumps into the
hallway's north wall at 6.4 s."""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from raspv_experiments.protocol import EXPERIMENTS_DIR
from raspv_experiments.quick_sweep import _graph_params, subject_config
from raspv_experiments.quick_trial import quick_trial
from raspv_experiments.session import read_jsonl
from raspv_experiments.sweep import load_sweep, run_sweep

pytestmark = [pytest.mark.integration, pytest.mark.slow]
SUBJECT = 3


def test_a_graph_trial_and_a_quick_trial_of_the_same_seed_agree_on_the_bump(tmp_path):
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "hallway.yaml").write_text((EXPERIMENTS_DIR / "worlds" / "hallway.yaml").read_text())
    doc = yaml.safe_load((EXPERIMENTS_DIR / "example.yaml").read_text())
    doc["tasks"]["hallway"]["time_limit"] = 8
    (tmp_path / "short.yaml").write_text(yaml.safe_dump(doc))
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump({
        "name": "touch", "protocol": "short.yaml", "policy": "navigate", "subjects": [SUBJECT],
        "factors": {"spv.num_phosphenes": [30]}, "repetitions": 1}))
    sweep = load_sweep(tmp_path / "sweep.yaml")
    task, condition = sweep.protocol.tasks[0], sweep.protocol.conditions[0]

    bumps = []                                   # the quick trial: sim time of each new collision
    spv = {**_graph_params(sweep, "spv"), **condition.params["spv"], "headless": True}
    quick = quick_trial(task.world, (task.start_x, task.start_y, math.radians(task.start_yaw_deg)),
                        (task.goal.x, task.goal.y, task.goal.radius), task.time_limit, spv=spv, policy="navigate",
                        config=subject_config(sweep, SUBJECT, SUBJECT * 100_003 + 1), rate=10, size=(160, 120),
                        on_frame=lambda sim: bumps.append(round(sim.t, 2)) if sim.monitor.count > len(bumps) else None)
    assert quick.collisions == 1 and bumps == [6.4]

    results = run_sweep(sweep, tmp_path / "out", workers=1, say=lambda s: None)
    assert results[0]["code"] == 0, results[0]["log"]
    record = read_jsonl(tmp_path / "out" / "sessions" / "touch" / f"scripted-navigate-{SUBJECT}" / "trials.jsonl")[0]
    metrics = record["metrics"]
    assert metrics["collisions"] == quick.collisions and metrics["success"] == quick.success
    trajectory = record["trajectory"]
    graph_path = np.column_stack([trajectory["x"], trajectory["y"]])[1:]     # its first sample is the start
    quick_path = np.asarray(quick.path)
    n = min(len(graph_path), len(quick_path))
    assert n >= 75
    apart = np.hypot(*(graph_path[:n] - quick_path[:n]).T)
    assert apart.max() < 0.1, f"the paths part by {apart.max():.2f} m at {trajectory['t'][1 + int(apart.argmax())]} s"
