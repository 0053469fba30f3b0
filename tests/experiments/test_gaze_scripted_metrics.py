"""Scripted gaze (raspv_experiments/scripted_gaze.py) and per-trial gaze metrics (gaze_metrics.py)."""
import math

import numpy as np
import pytest

from raspv_experiments.gaze_metrics import gaze_metrics, trial_gaze_metrics
from raspv_experiments.scripted_gaze import (GazeModelConfig, GazeScript, GazeTrace, directions_from_angles,
                                             displayed_layout_index, load_trace, main_sequence_s, model_trace)
from raspv_sim.experiment_log import ExperimentLog, read_gaze
from raspv_spv.gaze import angle_between_deg, direction_from_angles


def _trace(segments, rate=120.0):
    """A trace from (duration s, yaw deg) fixations joined by 40 ms linear saccades."""
    t, yaw = [], []
    now, here = 0.0, segments[0][1]
    for duration, target in segments:
        for _ in range(int(round(0.04 * rate))):                  # the saccade to it
            now += 1 / rate
            here += (target - here) / max(1, int(round((0.04 * rate))))
            t.append(now)
            yaw.append(here)
        here = target
        for _ in range(int(round(duration * rate))):
            now += 1 / rate
            t.append(now)
            yaw.append(target)
    return np.array(t), directions_from_angles(np.array(yaw), np.zeros(len(yaw)))


def test_metrics_of_a_known_trace():
    t, d = _trace([(0.3, 0.0), (0.25, 8.0), (0.4, 2.0), (0.3, -10.0)])
    valid = np.ones(len(t), bool)
    m = gaze_metrics(t, d, valid)
    assert m.fixations == 4 and m.saccades == 3
    assert m.mean_saccade_amplitude_deg == pytest.approx((8 + 6 + 12) / 3, abs=0.5)
    assert m.valid_share == 1.0
    valid[50:80] = False                                         # a blink of 30 samples (0.25 s)
    m = gaze_metrics(t, d, valid)
    assert m.valid_share == pytest.approx(1 - 30 / len(t), abs=0.01)
    empty = gaze_metrics(np.zeros(0), np.zeros((0, 3)), np.zeros(0, bool))
    assert empty.samples == 0 and math.isnan(empty.valid_share) and math.isnan(empty.mean_saccade_amplitude_deg)


def test_model_is_seeded_bounded_and_follows_its_statistics():
    a, b = model_trace(30.0, seed=3), model_trace(30.0, seed=3)
    assert np.array_equal(a.directions, b.directions) and np.array_equal(a.valid, b.valid)
    assert not np.array_equal(a.directions, model_trace(30.0, seed=4).directions)
    c = GazeModelConfig()
    ecc = np.degrees(np.arccos(np.clip(a.directions[:, 0], -1, 1)))
    assert ecc.max() < c.max_eccentricity_deg * 1.05 + 0.5
    m = gaze_metrics(a.t, a.directions, a.valid)
    # ~1 fixation per (fixation + saccade) time; the measured statistics near the model's
    assert 30.0 / (c.mean_fixation_s + main_sequence_s(c.mean_amplitude_deg)) * 0.6 < m.fixations < 30.0 / c.mean_fixation_s
    assert 3.0 < m.mean_saccade_amplitude_deg < 9.0
    assert 0.9 < m.valid_share < 1.0                             # blinks: 15/min of 150 ms ≈ 4 %
    assert main_sequence_s(12.0) == pytest.approx(0.0474)


def test_script_plays_the_trace_once_in_sim_time_and_repeats():
    trace = GazeTrace(np.array([0.0, 0.5, 1.0]), directions_from_angles(np.array([0.0, 5.0, 10.0]), np.zeros(3)),
                      np.array([True, False, True]))
    script = GazeScript(trace, origin=100.0)
    first = script.due(100.6)
    assert [s for s, _ in first] == [100.0, 100.5] and first[1][1] is None
    assert script.due(100.6) == []
    later = script.due(102.1)
    assert [round(s, 3) for s, _ in later] == [101.0, 101.5, 102.0]     # period 1.5 s: starts over


def test_trace_files_round_trip_and_bad_ones_are_one_line(tmp_path):
    trace = model_trace(2.0, seed=1)
    path = tmp_path / "gaze.csv"
    trace.save(path)
    back = load_trace(path)
    assert np.allclose(back.t, trace.t, atol=1e-6) and np.array_equal(back.valid, trace.valid)
    assert np.allclose(back.directions[back.valid], trace.directions[trace.valid], atol=1e-5)
    angles = tmp_path / "angles.csv"
    angles.write_text("t,yaw_deg,pitch_deg,valid\n0,10,0,1\n0.01,10,5,1\n")
    assert angle_between_deg(load_trace(angles).directions[1], direction_from_angles(10, 5)) < 1e-9
    for text, says in [("a,b\n1,2\n", "header"), ("t,x,y,z,valid\n0,1,0,0,1\n0,1,0,0,1\n", "does not increase"),
                       ("t,x,y,z,valid\n0,1,zero,0,1\n", "line 2"), ("t,x,y,z,valid\n", "no samples")]:
        bad = tmp_path / "bad.csv"
        bad.write_text(text)
        with pytest.raises(ValueError, match=says) as exc:
            load_trace(bad)
        assert "\n" not in str(exc.value)


def test_gaze_in_the_run_log_and_the_trial_metrics(tmp_path):
    log = ExperimentLog(tmp_path, "w", {}, rate=10.0, run_name="run", t0=50.0)
    t, d = _trace([(0.3, 0.0), (0.3, 6.0)])
    for ti, di in zip(t, d):
        log.gaze(50.0 + ti, 1000.0 + ti, tuple(di))
    log.gaze(50.0 + t[-1] + 0.01, 1000.0 + t[-1] + 0.01, None)
    log.close()
    cols = read_gaze(log.dir)
    assert len(cols["t"]) == len(t) + 1 and cols["valid"][-1] == 0 and math.isnan(cols["x"][-1])
    m = trial_gaze_metrics(log.dir, 50.0, 50.0 + t[-1] + 1)
    assert m.saccades == 1 and m.fixations == 2 and m.mean_saccade_amplitude_deg == pytest.approx(6.0, abs=0.1)
    assert trial_gaze_metrics(log.dir, 80.0, 90.0) is None


def test_displayed_layout_index_finds_the_phosphene_drawn_at_each_place():
    xs, ys = np.meshgrid(np.arange(5) * 10.0, np.arange(4) * 10.0)
    centres = np.column_stack([xs.ravel(), ys.ravel()])
    idx = displayed_layout_index(centres, (10.0, 0.0), 10.0)
    # phosphene (x=20, y=0) sees the one drawn there: (x=10, y=0) shifted right by 10
    assert idx[2] == 1 and idx[0] == -1
    assert np.array_equal(displayed_layout_index(centres, (0.0, 0.0), 10.0), np.arange(len(centres)))
