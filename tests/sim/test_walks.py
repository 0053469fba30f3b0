"""Simulated walks (raspv_sim.walks, `raspv sim walk`): the plan follows the route at the given
pace and closes its loops where it started, kidnaps cover the camera and carry the subject, and
the rendered sequence reads back through `raspv bag from-frames`' reader with its ground truth."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from raspv_sim.walks import Kidnap, WalkError, WalkSpec, load_walk, plan_walk

SQUARE = ((7.0, 2.0), (9.0, 2.0), (9.0, 5.0), (7.0, 5.0))     # the apartment's living room, 10 m round


def test_a_loop_is_walked_at_its_pace_and_ends_where_it_began():
    spec = WalkSpec("apartment", SQUARE, loops=2, speed=1.0, rate=30.0)
    plan = plan_walk(spec)
    assert plan.length_m == pytest.approx(20.0, abs=0.05)
    xy = np.array([(p.x, p.y) for p in plan.poses])
    steps = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert steps.max() <= 1.0 / 30.0 + 1e-9                   # never faster than the pace
    assert len(plan.loop_times) == 2
    for t in plan.loop_times:
        p = min(plan.poses, key=lambda q: abs(q.t - t))
        assert math.hypot(p.x - 7.0, p.y - 2.0) < 0.05
    # walking 20 m at 1 m/s plus seven 90° turns at 90°/s (it starts facing the first leg)
    assert plan.poses[-1].t == pytest.approx(20.0 + 7 * 1.0, abs=0.5)


def test_the_head_looks_down_and_sways():
    plan = plan_walk(WalkSpec("apartment", SQUARE, loops=1, head_pitch_deg=20.0, head_yaw_deg=12.0))
    pitch = np.degrees([p.head_pitch for p in plan.poses])
    yaw = np.degrees([p.head_yaw for p in plan.poses])
    assert 16.0 <= pitch.min() and pitch.max() <= 24.0
    assert yaw.max() == pytest.approx(12.0, abs=0.5) and yaw.min() == pytest.approx(-12.0, abs=0.5)


def test_a_kidnap_covers_the_camera_and_carries_the_subject():
    spec = WalkSpec("apartment", SQUARE, loops=1, rate=10.0, kidnaps=(Kidnap(at_s=3.0, covered_s=2.0, to_waypoint=2),))
    plan = plan_walk(spec)
    covered = [p for p in plan.poses if p.covered]
    assert len(covered) == 20
    assert covered[0].t == pytest.approx(3.0, abs=0.1)
    after = plan.poses[plan.poses.index(covered[-1]) + 1]
    assert (after.x, after.y) == pytest.approx(SQUARE[2])
    assert not after.covered


@pytest.mark.parametrize("bad, message", [
    (dict(waypoints=((0.0, 0.0),)), "two waypoints"),
    (dict(loops=0), "loops"),
    (dict(kidnaps=(Kidnap(1.0, 1.0, 9),)), "waypoint 9"),
])
def test_bad_walks_are_refused(bad, message):
    fields = dict(world="apartment", waypoints=SQUARE) | bad
    with pytest.raises(WalkError, match=message):
        WalkSpec(**fields)


def test_the_shipped_walks_load_and_are_long_enough():
    folder = Path(__file__).resolve().parents[2] / "raspv_sim" / "walks"
    office = plan_walk(load_walk(folder / "office_two_loops.yaml"))
    assert office.length_m >= 60.0 and len(office.loop_times) == 2
    wide = plan_walk(load_walk(folder / "office_two_loops_wide.yaml"))
    assert wide.length_m >= 60.0 and len(wide.loop_times) == 2
    kidnap = load_walk(folder / "office_kidnap.yaml")
    assert kidnap.kidnaps and kidnap.kidnaps[0].covered_s == 3.0


def test_a_rendered_walk_reads_back_with_its_ground_truth(tmp_path, private_cache):
    from raspv_bags.from_frames import discover_frames, read_depth

    walk = tmp_path / "walk.yaml"
    walk.write_text(yaml.safe_dump({"world": "apartment", "waypoints": [[7.0, 2.0], [7.6, 2.0]], "loops": 1,
                                    "rate": 10.0, "width": 160, "height": 120, "head_yaw_deg": 0.0}))
    out = tmp_path / "seq"
    run = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "sim", "walk", str(walk), "-o", str(out), "--flat"],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    frames = discover_frames(out)
    plan = plan_walk(load_walk(walk))
    assert frames.layout == "tum" and len(frames.pairs) == len(plan.poses)
    first = frames.pairs[0].pose
    # the camera at eye height over the route's first point, looking east (optical z ≈ +x)
    assert first[:2, 3] == pytest.approx([7.0, 2.0], abs=0.15) and 1.4 < first[2, 3] < 1.7
    assert first[0, 2] > 0.9
    depth = read_depth(frames.pairs[0].depth, frames.depth_format, frames.depth_scale)
    assert np.isfinite(depth).mean() > 0.5 and np.nanmax(depth) <= 6.0 + 1e-3       # realistic sensor's range
    meta = yaml.safe_load((out / "walk.yaml").read_text())
    assert meta["length_m"] == pytest.approx(1.2, abs=0.05)            # there and back


def test_a_leg_through_a_wall_is_found_and_one_around_it_is_not():
    from raspv_common.occupancy import OCCUPIED, OccupancyGrid
    from raspv_sim.walk_route import route_obstruction

    cells = np.zeros((40, 40), np.int8)                       # 4 m x 4 m at 0.1 m, a wall along x = 2 m
    cells[:30, 20] = OCCUPIED                                 # ... from y = 0 to 3 m: a gap at the north end
    grid = OccupancyGrid(cells, 0.1, (0.0, 0.0))
    blocked = route_obstruction([(1.0, 1.0), (3.0, 1.0), (3.0, 1.5)], grid)
    assert blocked is not None and blocked.distance == 0.0
    assert blocked.start == (1.0, 1.0) and blocked.at[0] == pytest.approx(2.0, abs=0.1)
    assert "(1, 1) -> (3, 1) goes through" in blocked.describe()
    assert route_obstruction([(1.0, 3.5), (3.0, 3.5)], grid) is None            # through the gap, both ways


def test_the_shipped_walks_go_through_doors_not_walls(private_cache):
    """Every leg of every shipped walk keeps clear of the world's walls and furniture: the office
    walks once crossed the open plan's east wall (the camera jumped through it and SLAM lost
    tracking)."""
    from raspv_sim.occupancy_export import world_occupancy
    from raspv_sim.simulator import SimConfig, Simulation
    from raspv_sim.walks import check_route

    folder = Path(__file__).resolve().parents[2] / "raspv_sim" / "walks"
    specs = [load_walk(p) for p in sorted(folder.glob("*.yaml"))]
    for world in sorted({s.world for s in specs}):
        with Simulation(world, SimConfig(width=16, height=12, renderer="tiny")) as sim:
            grid = world_occupancy(sim.world)
        for spec in (s for s in specs if s.world == world):
            check_route(spec, grid)


def test_a_walk_through_a_wall_is_refused_in_one_line(tmp_path, private_cache):
    walk = tmp_path / "walk.yaml"
    walk.write_text(yaml.safe_dump({"world": "office", "waypoints": [[13.3, 8.0], [9.5, 8.0]], "loops": 1,
                                    "width": 160, "height": 120}))
    out = tmp_path / "seq"
    run = subprocess.run([sys.executable, "-m", "raspv_bringup.cli", "sim", "walk", str(walk), "-o", str(out), "--flat"],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode != 0 and "Traceback" not in run.stderr
    assert "(13.3, 8) -> (9.5, 8) goes through a wall" in run.stderr.strip().splitlines()[-1]
    assert not out.exists()
