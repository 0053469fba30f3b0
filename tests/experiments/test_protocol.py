"""Protocol files: the documented example loads; every mistake is one line naming file, key and what is allowed."""
from __future__ import annotations

import copy

import pytest

from raspv_experiments.protocol import EXPERIMENTS_DIR, ProtocolError, load_protocol

EXAMPLE = EXPERIMENTS_DIR / "example.yaml"



def errors_of(write_protocol, doc) -> list[str]:
    with pytest.raises(ProtocolError) as err:
        load_protocol(write_protocol(doc))
    return err.value.errors


def test_the_documented_example_loads():
    p = load_protocol(EXAMPLE)
    assert p.name == "example"
    assert [c.name for c in p.conditions] == ["depth", "downsampling"]
    assert p.conditions[0].params == {"spv": {"mode": "depth"}}
    task = p.tasks[0]
    assert (task.start_x, task.start_y, task.goal.radius, task.time_limit) == (1.0, 2.1, 0.8, 40.0)
    assert p.design.repetitions == 3 and p.design.order == "latin_square"
    assert [n.kind for n in p.graph.nodes] == ["sim", "spv", "bridge"]
    # every parameter a condition sets is reset to the graph's value (or the node's default) for the others
    assert p.controlled == {"spv": {"mode": "grey"}}
    assert p.trial_params("depth") == {"spv": {"mode": "depth"}}


def test_conditions_do_not_leak_into_each_other(write_protocol, example_doc):
    doc = copy.deepcopy(example_doc)
    doc["conditions"] = {"a": {"spv": {"mode": "depth", "dropout": 0.2}}, "b": {"spv": {"num_phosphenes": 100}}}
    p = load_protocol(write_protocol(doc))
    assert p.trial_params("a") == {"spv": {"mode": "depth", "dropout": 0.2, "num_phosphenes": 0}}
    assert p.trial_params("b") == {"spv": {"mode": "grey", "dropout": -1.0, "num_phosphenes": 100}}


def test_goals_from_objects_and_world_goals(write_protocol, example_doc):
    doc = copy.deepcopy(example_doc)
    doc["tasks"]["crate"] = {**doc["tasks"]["hallway"], "goal": {"object": "crate", "within": 1.2}}
    doc["tasks"]["end"] = {**doc["tasks"]["hallway"], "goal": {"name": "far_end"}}
    p = load_protocol(write_protocol(doc))
    crate, end = p.task("crate").goal, p.task("end").goal
    assert (crate.x, crate.y, crate.radius, crate.label) == (4.0, 2.1, 1.2, "crate")
    assert (end.x, end.y, end.radius, end.label) == (9.0, 1.5, 0.6, "far_end")


@pytest.mark.parametrize("change, expected", [
    (lambda d: d["conditions"]["depth"]["spv"].update(mode="dpth"),
     "conditions.depth.spv.mode: 'dpth' is not allowed; expected string one of"),
    (lambda d: d["conditions"]["depth"]["spv"].update(colour=1),
     "conditions.depth.spv.colour: unknown parameter; this node has:"),
    (lambda d: d["conditions"]["depth"]["spv"].update(headless=True),
     "conditions.depth.spv.headless: cannot change while the graph runs; set it in the graph section"),
    (lambda d: d["conditions"]["depth"].update(planner={"goal": [1, 2]}),
     "conditions.depth.planner: no node named 'planner' in the graph (nodes: sim, spv, bridge)"),
    (lambda d: d["tasks"]["hallway"].update(goal={"object": "sofa"}),
     "tasks.hallway.goal.object: 'sofa' is not an object of world hallway; objects: crate, planter"),
    (lambda d: d["tasks"]["hallway"].update(goal={"position": [1, 2], "object": "crate"}),
     "tasks.hallway.goal: give exactly one of position"),
    (lambda d: d["tasks"]["hallway"].update(world="nowhere"),
     "tasks.hallway.world: "),
    (lambda d: d["tasks"]["hallway"].update(time_limit=-3),
     "tasks.hallway.time_limit: expected a positive number, got -3"),
    (lambda d: d["tasks"]["hallway"]["start"].update(position=[1]),
     "tasks.hallway.start.position: expected [x, y] in metres, got [1]"),
    (lambda d: d["tasks"]["hallway"]["start"].update(position=[4.0, 2.1]),
     "tasks.hallway.start.position: the avatar at [4, 2.1] overlaps box 'crate'"),
    (lambda d: d["design"].update(order="balanced"),
     "design.order: 'balanced' is not allowed; expected one of fixed, random, latin_square"),
    (lambda d: d["design"].update(repetitions=0), "design.repetitions: expected an integer in [1, 1000], got 0"),
    (lambda d: d["design"].update(blocks_of=2), "design.blocks_of: unknown key; allowed:"),
    (lambda d: d["graph"]["spv"]["ros__parameters"].update(mode="nonsense"),
     "graph.spv.ros__parameters.mode: 'nonsense' is not allowed"),
    (lambda d: d.pop("tasks"), "tasks: missing; see experiments/example.yaml"),
    (lambda d: d["record"].update(bag="yes"), "record.bag: expected true or false, got 'yes'"),
])
def test_each_mistake_is_one_line_naming_file_and_key(write_protocol, example_doc, change, expected):
    doc = copy.deepcopy(example_doc)
    change(doc)
    errors = errors_of(write_protocol, doc)
    assert len(errors) == 1, errors
    assert "protocol.yaml: " in errors[0] and expected in errors[0], errors[0]
    assert "\n" not in errors[0] and "Traceback" not in errors[0]


def test_broken_yaml_and_missing_file_are_one_line(write_protocol, tmp_path):
    errors = errors_of(write_protocol, "name: x\nconditions: [a\n")
    assert len(errors) == 1 and "invalid YAML" in errors[0] and "line " in errors[0]
    with pytest.raises(ProtocolError, match="no such protocol file"):
        load_protocol(tmp_path / "absent.yaml")
    errors = errors_of(write_protocol, "- just\n- a list\n")
    assert errors == [f"{tmp_path / 'protocol.yaml'}: expected a mapping with graph, conditions, tasks and design"]


# Shipped protocols that compare representations but still run noise-free depth, and why.
NOISE_FREE_MODE_COMPARISONS: dict[str, str] = {}


def test_protocols_that_compare_modes_run_realistic_depth_by_default():
    """Noise-free depth favours the depth-based modes; a protocol whose conditions show different
    representations runs the simulator's depth sensor (noise, quantisation, holes) unless listed
    above with its reason (issue 33)."""
    compared = {}
    for path in sorted(EXPERIMENTS_DIR.glob("*.yaml")):
        try:
            protocol = load_protocol(path)
        except ProtocolError:
            continue                                  # sweep files and the like: not protocols
        base = protocol.graph.node("spv").params.get("mode", "depth")
        modes = {c.params.get("spv", {}).get("mode", base) for c in protocol.conditions}
        if len(modes) > 1:
            compared[protocol.name] = bool(protocol.graph.node("sim").params.get("depth_noise", False))
    assert {"example", "hallway_modes", "office_navigation"} <= set(compared)
    assert {n for n, noisy in compared.items() if not noisy} == set(NOISE_FREE_MODE_COMPARISONS)
