"""Per-trial metrics from a real simulator log: success, times, path length and efficiency, collisions,
clearance, head rotation."""
from __future__ import annotations

import math

import numpy as np
import pytest

from raspv_experiments.protocol import EXPERIMENTS_DIR
from raspv_experiments.metrics import head_rotation_deg, trajectory_record, trial_metrics
from raspv_experiments.world_geometry import clip_to_region, world_geometry
from raspv_sim.collision_events import CollisionEvent
from raspv_sim.experiment_log import ExperimentLog, TrajectorySample

HALLWAY = str(EXPERIMENTS_DIR / "worlds" / "hallway.yaml")


def write_run(tmp_path, goal_at: float | None, collisions=(), head_yaw=None):
    """A straight walk along +x at 0.5 m/s from (1, 1.5), logged at 10 Hz from sim time 100 s."""
    log = ExperimentLog(tmp_path, "hallway", {"goals": []}, rate=10.0, run_name="trial")
    for k in range(0, 101):
        t = 100.0 + 0.1 * k
        x = 1.0 + 0.05 * k
        yaw_h = 0.0 if head_yaw is None else head_yaw(k)
        log.sample(TrajectorySample(t, x, 1.5, 0.0, 0.0, 0.0, 0.0, yaw_h, x, 1.5, 1.6, 0.5, 0.0, 0.05 * k))
        if goal_at is not None and abs(t - goal_at) < 1e-9:
            log.goal("task:end", t)
    for t, name, cls in collisions:
        log.collision(CollisionEvent(t, name, cls, (0, 0, 0), (1, 0, 0), 0.5, 1))
    log.close()
    return log.dir


def test_successful_trial(tmp_path):
    run = write_run(tmp_path, goal_at=108.0, collisions=[(103.0, "crate", "box"), (104.0, "hallway_north", "wall")])
    m = trial_metrics(run, 100.0, 108.0, False, 40.0, "task:end", shortest_path_m=3.6)
    assert m.success and m.outcome == "goal"
    assert m.completion_time_s == pytest.approx(8.0)
    assert m.path_length_m == pytest.approx(4.0)          # walked up to the goal
    assert m.path_efficiency == pytest.approx(0.9)
    assert (m.collisions, m.collided_with, m.collisions_by_class) == (2, ["box:crate", "wall:hallway_north"],
                                                                     {"box": 1, "wall": 1})
    assert m.head_rotation_deg == 0.0 and math.isnan(m.min_clearance_m)


def test_failed_and_aborted_trials(tmp_path):
    run = write_run(tmp_path, goal_at=None)
    m = trial_metrics(run, 100.0, 110.0, False, 10.0, "task:end", 3.6)
    assert (m.success, m.outcome, m.completion_time_s, m.duration_s) == (False, "time_limit", 10.0, 10.0)
    assert math.isnan(m.path_efficiency) and m.path_length_m == pytest.approx(5.0)
    a = trial_metrics(run, 100.0, 104.0, True, 10.0, "task:end", 3.6)
    assert (a.outcome, a.duration_s, a.path_length_m) == ("aborted", 4.0, pytest.approx(2.0))


def test_head_rotation_sums_angles_between_samples(tmp_path):
    yaws = np.radians([0, 10, 20, 10, 0])
    assert head_rotation_deg(np.zeros(5), np.zeros(5), yaws) == pytest.approx(40.0, abs=1e-6)
    assert head_rotation_deg(np.zeros(3), np.radians([0, 30, 0]), np.zeros(3)) == pytest.approx(60.0, abs=1e-6)
    run = write_run(tmp_path, None, head_yaw=lambda k: math.radians(5.0 * (k % 2)))   # 5 deg every 0.1 s
    m = trial_metrics(run, 100.0, 110.0, False, 10.0, "task:end", 3.6)
    assert m.head_rotation_deg == pytest.approx(500.0, rel=1e-3)
    assert m.head_rotation_deg_per_s == pytest.approx(50.0, rel=1e-3)
    rec = trajectory_record(run, 100.0, 101.0)
    assert rec["t"][0] == 0.0 and rec["t"][-1] == pytest.approx(1.0) and len(rec["x"]) == 11


def test_clearance_and_shortest_path_in_a_real_world(tmp_path):
    geo = world_geometry(HALLWAY)
    # the hallway is 3 m wide: in its middle a 0.25 m body is 1.5 - 0.06 (half a wall) - 0.25 m from the walls
    c = geo.clearance(np.array([[2.0, 1.5], [4.0, 1.5]]))
    assert c[0] == pytest.approx(1.5 - 0.06 - 0.25, abs=0.03)          # the stated tolerance: ±3 cm
    assert c[1] == pytest.approx(2.1 - 0.3 - 1.5 - 0.25, abs=0.03)      # the crate's near side is at y = 1.8
    touching = geo.clearance(np.array([[4.0, 1.8 - 0.25], [1.0, 0.06 + 0.25]]))        # body against the crate, a wall
    assert touching == pytest.approx([0.0, 0.0], abs=0.03)
    path, length = geo.shortest_path((1.0, 1.5), (8.6, 1.5), 0.8)
    assert length == pytest.approx(8.6 - 0.8 - 1.0, abs=0.15)           # straight along the hallway's free middle
    assert np.linalg.norm(path[-1] - [8.6, 1.5]) == pytest.approx(0.8, abs=1e-6)
    # a goal on an object: the nearest place the body can stand within reach
    _, to_crate = geo.shortest_path((1.0, 1.5), (4.0, 2.1), 1.0)
    assert 1.5 < to_crate < 3.0
    run = write_run(tmp_path, goal_at=108.0)
    m = trial_metrics(run, 100.0, 108.0, False, 40.0, "task:end", length, geo)
    assert m.min_clearance_m == pytest.approx(1.8 - 1.5 - 0.25, abs=0.06)   # passing the crate at y = 1.5


def test_clip_to_region():
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    cut, length = clip_to_region(path, np.array([10.0, 0.0]), 2.0)
    assert length == pytest.approx(8.0) and cut[-1] == pytest.approx([8.0, 0.0])
    assert clip_to_region(path, np.array([0.0, 0.5]), 1.0)[1] == 0.0
