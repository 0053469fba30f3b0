"""A lockstep graph trial and a quick trial of the same virtual subject and seed walk the same
path, bump alike and end alike, over a whole 20 s trial with realistic depth (the example's
default). Three differences between the two loops made them part (issue 33), each fixed:

- touch: the graph's subject did not feel bumps at all (0.38 m apart 1.6 s after the first), then
  felt one a frame late when the executor handed it the phosphene frame before the collision;
- time: the policy compared ages on the simulator's absolute, nanosecond-rounded time (an
  obstacle seen 40 frames ago was 3.9999999999999996 s old in one loop, 4.000000000000001 s in
  the other, and forgotten a frame apart), and the collision debounce did the same: the paths
  parted by millimetres after ~7 s, and by 2.1 m with another outcome at 20 s (subject 2 at
  16 phosphenes: 3 collisions and the time limit in the quick trial, 2 and the goal in the graph);
- the sensor's noise came from one stream since the graph started, so it depended on what the
  graph rendered before the trial.
Virtual subject 2 at 16 phosphenes bumps three times in the hallway."""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest
import yaml

from raspv_experiments.design import trial_seed
from raspv_experiments.protocol import EXPERIMENTS_DIR
from raspv_experiments.quick_sweep import _graph_params, subject_config
from raspv_experiments.quick_trial import quick_trial
from raspv_experiments.session import read_jsonl
from raspv_experiments.sweep import load_sweep, run_sweep

pytestmark = [pytest.mark.integration, pytest.mark.slow]
SUBJECT, PHOSPHENES, LIMIT = 2, 16, 20


def test_a_graph_trial_and_a_quick_trial_of_the_same_seed_agree_over_the_whole_trial(tmp_path):
    (tmp_path / "worlds").mkdir()
    (tmp_path / "worlds" / "hallway.yaml").write_text((EXPERIMENTS_DIR / "worlds" / "hallway.yaml").read_text())
    doc = yaml.safe_load((EXPERIMENTS_DIR / "example.yaml").read_text())
    doc["graph"]["sim"]["ros__parameters"]["depth_noise"] = True                # realistic depth
    doc["tasks"]["hallway"]["time_limit"] = LIMIT
    (tmp_path / "short.yaml").write_text(yaml.safe_dump(doc))
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump({
        "name": "touch", "protocol": "short.yaml", "policy": "navigate", "subjects": [SUBJECT],
        "factors": {"spv.num_phosphenes": [PHOSPHENES]}, "repetitions": 1}))
    sweep = load_sweep(tmp_path / "sweep.yaml")
    task, condition = sweep.protocol.tasks[0], sweep.protocol.conditions[0]

    bumps = []                                   # the quick trial: sim time of each new collision
    spv = {**_graph_params(sweep, "spv"), **condition.params["spv"], "headless": True}
    quick = quick_trial(task.world, (task.start_x, task.start_y, math.radians(task.start_yaw_deg)),
                        (task.goal.x, task.goal.y, task.goal.radius), task.time_limit, spv=spv, policy="navigate",
                        config=subject_config(sweep, SUBJECT, trial_seed(SUBJECT, 1)), rate=10, size=(160, 120),
                        sim_params=_graph_params(sweep, "sim"),
                        on_frame=lambda sim: bumps.append(round(sim.t, 2)) if sim.monitor.count > len(bumps) else None)
    assert quick.collisions == 3 and len(bumps) == 3 and not quick.success

    results = run_sweep(sweep, tmp_path / "out", workers=1, say=lambda s: None)
    assert results[0]["code"] == 0, results[0]["log"]
    folder = tmp_path / "out" / "sessions" / "touch" / f"scripted-navigate-{SUBJECT}"
    metrics = read_jsonl(folder / "trials.jsonl")[0]["metrics"]
    assert (metrics["collisions"], metrics["success"]) == (quick.collisions, quick.success)
    events = [e for f in folder.glob("trials/*/events.jsonl") for e in read_jsonl(f) if e["event"] == "collision"]
    assert [round(e["t"], 1) for e in events] == [round(b, 1) for b in bumps]          # the quick trial starts at 0
    with open(next(folder.glob("trials/*/trajectory.csv")), newline="") as handle:     # 4 decimals
        graph_path = np.array([[float(r["x"]), float(r["y"])] for r in csv.DictReader(handle)])[1:]
    quick_path = np.asarray(quick.path)
    n = min(len(graph_path), len(quick_path))
    assert n >= 195
    apart = np.hypot(*(graph_path[:n] - quick_path[:n]).T)
    assert apart.max() < 1e-3, f"the paths part by {apart.max():.4f} m at sample {int(apart.argmax())}"
