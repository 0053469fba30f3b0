"""tools/slam_long_walk.py: a building of rooms and a walk through every one of them once, for
SLAM's 10-minute memory target. The default walk lasts ten minutes and more, and a building's
route goes through doors, never through a wall or furniture (the render would refuse it)."""
import importlib.util
from pathlib import Path

import pytest
import yaml

from raspv_sim.walks import WalkSpec, check_route, plan_walk
from raspv_sim.world_spec import parse_world

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("slam_long_walk", ROOT / "tools/slam_long_walk.py")
long_walk = importlib.util.module_from_spec(spec)
spec.loader.exec_module(long_walk)


def _walk_spec(walk: dict, world: str) -> WalkSpec:
    return WalkSpec(world=world, waypoints=tuple(tuple(p) for p in walk["waypoints"]), loops=walk["loops"],
                    speed=walk["speed"], rate=walk["rate"])


def test_the_default_walk_lasts_ten_minutes():
    world, walk = long_walk.building(8, 7, (10.0, 5.0), 0, 10.0, 1.0)
    plan = plan_walk(_walk_spec(walk, "long_building"))
    assert plan.poses[-1].t >= 600.0 and len(plan.loop_times) == 1
    assert len(world["rooms"]) == 56


def test_a_building_walk_goes_through_doors(tmp_path, private_cache):
    from raspv_sim.occupancy_export import world_occupancy
    from raspv_sim.simulator import SimConfig, Simulation

    world, walk = long_walk.building(2, 3, (8.0, 5.0), 1, 10.0, 1.0)
    parse_world(world)                                            # a valid world file
    path = tmp_path / "building.yaml"
    path.write_text(yaml.safe_dump(world))
    with Simulation(str(path), SimConfig(width=16, height=12, renderer="tiny")) as sim:
        grid = world_occupancy(sim.world)
    check_route(_walk_spec(walk, str(path)), grid)


def test_an_odd_number_of_rows_is_refused():
    with pytest.raises(ValueError, match="even number of rows"):
        long_walk.building(3, 4, (10.0, 5.0), 0, 10.0, 1.0)
