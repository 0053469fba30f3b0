"""The obstacle course after de Ruyter van Steveninck et al. 2022 and its phosphene-count sweep:
the world loads, its boxes are the study's sizes, a straight walk collides while a path exists;
the protocol and sweep files are valid and runnable in one process; the quick sweep's summary
(bootstrap CIs over subjects) is right on known records. The sweep itself is not run here
(≈ 30 min: docs/experiments.md has its numbers)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from raspv_experiments.quick_sweep import QuickTrialRecord, check_quick, summarise, summary_table
from raspv_experiments.sweep import load_sweep

REPO = Path(__file__).resolve().parents[2]
WORLD = REPO / "experiments" / "worlds" / "obstacle_course.yaml"


def test_the_course_loads_with_the_studys_boxes_and_blocks_a_straight_walk():
    from raspv_experiments.world_geometry import world_geometry
    from raspv_sim.world_check import check_world

    spec = check_world(str(WORLD))
    boxes = [f for f in spec.furniture if f.type == "box"]
    sizes = sorted(tuple(round(v, 2) for v in b.size) for b in boxes)
    assert sizes.count((0.3, 0.5, 0.9)) == 7 and sizes.count((0.3, 0.75, 1.8)) == 6      # 7 small, 6 large
    geo = world_geometry(str(WORLD))
    line = np.column_stack([np.linspace(1.0, 23.0, 441), np.full(441, 1.5)])            # straight down the middle
    hits = geo.clearance(line) < 0.0
    assert hits.any()
    path, length = geo.shortest_path((1.0, 1.5), (24.0, 1.5), 1.6)
    assert math.isfinite(length) and 21.0 < length < 26.0                                 # it can be walked, around


def test_the_sweep_file_is_valid_and_runs_in_one_process():
    sweep = load_sweep(REPO / "experiments" / "obstacle_course_sweep.yaml")
    counts = [c.params["spv"]["num_phosphenes"] for c in sweep.protocol.conditions]
    assert counts == sorted(counts) and counts[0] <= 16 and counts[-1] >= 2500
    assert sweep.policy == "navigate" and len(sweep.subjects) >= 6
    assert {c.params.get("spv", {}).get("mode", "depth") for c in sweep.protocol.conditions} == {"depth"}
    assert sweep.protocol.graph.node("spv").params["mode"] == "depth"
    assert check_quick(sweep) == []
    assert list(sweep.protocol.factors) == ["spv.num_phosphenes"]


def test_the_in_range_sweep_has_the_studys_six_counts_and_realistic_depth():
    sweep = load_sweep(REPO / "experiments" / "obstacle_course_range_sweep.yaml")
    counts = [c.params["spv"]["num_phosphenes"] for c in sweep.protocol.conditions]
    assert counts == [n * n for n in (10, 18, 26, 34, 42, 50)]
    assert sweep.protocol.graph.node("sim").params["depth_noise"] is True
    assert len(sweep.subjects) == 12 and sweep.protocol.design.order == "latin_square"    # two 6×6 squares
    assert check_quick(sweep) == []


def _record(subject, level, success, collisions, time_s):
    return QuickTrialRecord(subject, f"n={level}", {"spv.num_phosphenes": str(level)}, "course", 1, success,
                            time_s if success else math.nan, time_s, collisions, 10.0, level, 1.0)


def test_the_summary_gives_means_over_subjects_with_bootstrap_intervals():
    records = [_record(s, 16, s % 2 == 0, 6 + s % 3, 90.0) for s in range(1, 9)]
    records += [_record(s, 100, True, s % 2, 50.0 + s) for s in range(1, 9)]
    rows = summarise(records, {"course": 90.0}, "spv.num_phosphenes", ["16", "100"])
    low, high = rows
    assert [r.level for r in rows] == ["16", "100"] and low.subjects == 8
    assert low.success == 0.5 and high.success == 1.0 and high.success_ci == (1.0, 1.0)
    assert low.success_ci[0] < 0.5 < low.success_ci[1]
    assert low.time_s == 90.0                      # not reached: counted at the time limit
    assert math.isclose(high.time_s, 54.5) and high.time_ci[0] < 54.5 < high.time_ci[1]
    assert low.collisions_ci[0] <= low.collisions <= low.collisions_ci[1]
    assert summarise(records, {"course": 90.0}, "spv.num_phosphenes")[0].level == "16"        # seeded: same table
    assert "| 100 |" in summary_table(rows, "spv.num_phosphenes")


def test_a_sweep_that_needs_the_scene_node_is_refused_by_the_quick_runner():
    problems = check_quick(load_sweep(REPO / "experiments" / "office_modes_sweep.yaml"))
    assert problems and all("needs the scene node" in p or "raspv experiment sweep" in p for p in problems)
