"""World files: every shipped world loads, builds and maps; malformed files fail in one line."""
from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml

from raspv_common.occupancy import FREE, OCCUPIED
from raspv_sim.occupancy_export import world_occupancy
from raspv_sim.simulator import SimConfig, Simulation
from raspv_sim.world_spec import (BUILTIN_CLASSES, WORLDS_DIR, WorldFileError, load_world, parse_world,
                                  shipped_worlds)

SMALL = SimConfig(width=32, height=24, renderer="tiny")

MINIMAL = {
    "floor": {"from": [0, 0], "to": [6, 4]},
    "rooms": [{"name": "room", "from": [0, 0], "to": [6, 4], "doors": [{"wall": "south", "at": 3.0, "width": 0.9}]}],
    "furniture": [{"type": "table", "name": "desk", "position": [3, 2]},
                  {"type": "chair", "position": [3, 2.7], "yaw": -90}],
    "spawn": {"position": [1, 1], "yaw": 0},
}


def test_three_worlds_are_shipped():
    assert {"apartment", "stairs", "office"} <= set(shipped_worlds())


@pytest.mark.parametrize("name", ["apartment", "stairs", "office", "grocery"])
def test_shipped_world_loads_builds_and_has_a_sensible_map(name):
    spec = load_world(name)
    assert spec.classes[:len(BUILTIN_CLASSES)] == BUILTIN_CLASSES
    with Simulation(spec, SMALL) as sim:
        # every body is labelled with a class of the table
        for info in sim.world.bodies.values():
            assert info.class_id == spec.classes.index(info.cls) and info.class_id > 0
        grid = world_occupancy(sim.world, resolution=0.1)
    spawn_cell = grid.world_to_cell([spec.spawn_position])[0]
    assert grid.cells[spawn_cell[0], spawn_cell[1]] == FREE
    for wall in spec.walls[:3]:   # the middle of a solid stretch of wall is occupied
        stretch = [s for s in np.linspace(0.1, 0.9, 17) * wall.length
                   if all(abs(s - d.at) > d.width / 2 + 0.15 for d in wall.doors)]
        s = stretch[len(stretch) // 2]
        point = np.add(wall.start, np.subtract(wall.end, wall.start) / wall.length * s)
        cell = grid.world_to_cell([point])[0]
        assert grid.cells[cell[0], cell[1]] == OCCUPIED, f"{wall.name} at {s:.2f} m is not occupied"
    free = (grid.cells == FREE).mean()
    assert 0.4 < free < 0.95


def test_specific_content_of_the_shipped_worlds():
    apartment, stairs, office = (load_world(n) for n in ("apartment", "stairs", "office"))
    assert {"sofa", "table", "chair", "shelf"} <= {f.cls for f in apartment.furniture}
    assert {s.direction for s in stairs.stairs} == {"up", "down"}
    assert any(f.type == "bin" for f in office.furniture) and [g.name for g in office.goals] == ["bin"]
    assert office.people and any(d.leaf is not None for w in office.walls for d in w.doors)
    assert {m.kind for m in office.models} == {"urdf", "obj"}


def test_defaults_and_generated_names():
    spec = parse_world(copy.deepcopy(MINIMAL), "mini.yaml")
    assert [w.name for w in spec.walls] == ["room/south", "room/east", "room/north", "room/west"]
    assert spec.walls[0].doors[0].height == pytest.approx(2.05)
    assert [f.name for f in spec.furniture] == ["desk", "chair1"]
    assert spec.furniture[0].size == (1.2, 0.8, 0.75) and spec.furniture[1].cls == "chair"


def _broken(path: list, value) -> dict:
    data = copy.deepcopy(MINIMAL)
    node = data
    for key in path[:-1]:
        node = node[key]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return data


_DELETE = object()

MISTAKES = [
    (["furniture", 0, "size"], [1.2, 0.8], "furniture[0] (table 'desk'): 'size' must be 3 positive numbers, got [1.2, 0.8]"),
    (["furniture", 0, "size"], [1.2, -0.8, 0.7], "furniture[0] (table 'desk'): 'size' must be 3 positive numbers"),
    (["furniture", 1, "type"], "armchair", "furniture[1]: 'type' must be one of table, chair, sofa"),
    (["furniture", 0, "colour"], "red", "furniture[0] (table 'desk'): unknown key 'colour' (allowed: class, color"),
    (["furniture", 0, "color"], [300, 0, 0], "'color' must be [r, g, b] in 0..1"),
    (["furniture", 1, "name"], "desk", "furniture[1] (chair 'desk'): name 'desk' is already used by furniture[0]"),
    (["rooms", 0, "doors", 0, "at"], 5.8, "rooms[0] ('room'): south wall: doors[0]: the opening [5.35, 6.25] m does not fit"),
    (["rooms", 0, "doors", 0, "wall"], "up", "rooms[0] ('room'): doors[0]: 'wall' must be one of south, east, north, west"),
    (["spawn", "position"], [10, 10], "spawn: 'position' [10.0, 10.0] is outside the floor"),
    (["spawn"], _DELETE, "top level: 'spawn' is missing"),
    (["floor", "to"], [-1, 4], "floor: 'to' [-1.0, 4.0] must be above and right of 'from'"),
    (["stairs"], [{"direction": "sideways", "position": [1, 1]}], "stairs[0] ('stairs0'): 'direction' must be one of up, down"),
    (["stairs"], [{"direction": "down", "position": [1, 1], "yaw": 30}], "a descending staircase's 'yaw' must be a multiple of 90"),
    (["stairs"], [{"direction": "up", "position": [1, 1], "steps": 2.5}], "'steps' must be a whole number"),
    (["people"], [{"waypoints": [[1, 1]]}], "people[0] ('person0'): 'waypoints' must be a list of at least 2 [x, y] points"),
    (["models"], [{"name": "ghost", "file": "nowhere/ghost.obj"}], "models[0] ('ghost'): 'file' nowhere/ghost.obj not found"),
    (["models"], [{"name": "pic", "file": "pic.png"}], "'file' must be an .obj mesh, a .urdf or an .sdf model"),
    (["furniture"], "table", "'furniture' must be a list"),
    (["goals"], [{"position": [1, 1]}], "goals[0]: 'name' is missing"),
    (["walls"], [{"from": [1, 1], "to": [1, 1]}], "walls[0] ('wall0'): 'from' and 'to' are the same point"),
]


@pytest.mark.parametrize("path, value, expected", MISTAKES, ids=[m[2][:40] for m in MISTAKES])
def test_malformed_world_fails_with_one_line_naming_the_entry(tmp_path, path, value, expected):
    f = tmp_path / "broken.yaml"
    f.write_text(yaml.safe_dump(_broken(path, value), sort_keys=False))
    with pytest.raises(WorldFileError) as info:
        load_world(f)
    message = str(info.value)
    assert "\n" not in message
    assert message.split(": ")[0].endswith("broken.yaml")
    assert expected in message, message


def test_invalid_yaml_and_unknown_names(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_text("floor: {from: [0, 0], to: [1, 1]\nspawn: x\n")
    with pytest.raises(WorldFileError, match=r"bad.yaml: line \d+, column \d+: invalid YAML"):
        load_world(f)
    with pytest.raises(WorldFileError, match="unknown world 'atlantis': shipped worlds are apartment, grocery, office, stairs"):
        load_world("atlantis")
    with pytest.raises(WorldFileError, match="no such world file"):
        load_world(tmp_path / "missing.yaml")


def test_model_files_resolve_relative_to_the_world_and_to_pybullet_data(tmp_path):
    data = copy.deepcopy(MINIMAL)
    data["models"] = [{"name": "lamp", "file": str(WORLDS_DIR / "meshes" / "floor_lamp.obj"), "class": "lamp",
                       "position": [5, 3]},
                      {"name": "duck", "file": "pybullet_data:duck_vhacd.urdf", "class": "toy", "position": [4, 1]},
                      {"name": "rack", "file": "pybullet_data:kiva_shelf/model.sdf", "class": "shelf",
                       "position": [1.5, 3.0], "yaw": 90, "scale": 0.5}]
    f = tmp_path / "w.yaml"
    f.write_text(yaml.safe_dump(data))
    spec = load_world(f)
    assert spec.classes[-2:] == ("lamp", "toy")
    with Simulation(spec, SMALL) as sim:
        bodies = {b.name: uid for uid, b in sim.world.bodies.items()}
        assert {"lamp", "duck", "rack"} <= set(bodies)
        lo, hi = sim.client.getAABB(bodies["lamp"])
        assert (lo[2], hi[2]) == pytest.approx((0.0, 1.62), abs=0.02)       # the OBJ stands on the floor
        rack = sim.client.getBasePositionAndOrientation(bodies["rack"])[0]
        # the SDF's own model pose (0, 1 m) is kept relative to the placement: scaled 0.5, turned 90°
        assert rack[:2] == pytest.approx((1.5 - 0.5, 3.0), abs=1e-6)


def test_a_model_pybullet_cannot_load_fails_with_one_line(tmp_path):
    bad = tmp_path / "broken.urdf"
    bad.write_text("<robot name='x'><link name='a'><visual><geometry><mesh filename='nope.stl'/></geometry></visual>"
                   "</link></robot")
    data = copy.deepcopy(MINIMAL)
    data["models"] = [{"name": "thing", "file": str(bad)}]
    f = tmp_path / "w.yaml"
    f.write_text(yaml.safe_dump(data))
    with pytest.raises(WorldFileError) as info:
        Simulation(f, SMALL)
    assert "models[0] ('thing'): PyBullet could not load" in str(info.value) and "\n" not in str(info.value)



@pytest.mark.parametrize("spawn, problem", [([3.0, 2.0], "overlaps table 'desk'"),
                                            ([5.0, 5.0], "has no floor under it")])
def test_a_spawn_the_avatar_cannot_stand_on_is_one_line(tmp_path, spawn, problem):
    data = copy.deepcopy(MINIMAL)
    data["floor"]["to"] = [6, 6]
    data["stairs"] = [{"direction": "down", "position": [5.0, 4.0], "yaw": 90, "steps": 6, "landing": 0.5}]
    data["spawn"]["position"] = spawn
    f = tmp_path / "w.yaml"
    f.write_text(yaml.safe_dump(data))
    with pytest.raises(WorldFileError) as info:
        Simulation(f, SMALL)
    assert str(info.value).endswith(f"spawn: the avatar at {spawn} {problem}" + (
        " (its body is a 0.25 m radius cylinder)" if "overlaps" in problem else " (within the step height of z = 0)"))
