"""Sweep files: factors expand into conditions; mistakes are one line naming the file and key."""
from __future__ import annotations

import pytest
import yaml

from raspv_experiments.protocol import EXPERIMENTS_DIR, ProtocolError
from raspv_experiments.sweep import load_sweep


def write(tmp_path, doc) -> str:
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(doc))
    return str(path)


def test_factors_make_every_combination(tmp_path):
    s = load_sweep(write(tmp_path, {
        "name": "s", "protocol": str(EXPERIMENTS_DIR / "example.yaml"), "policy": "wander_avoid", "subjects": 3,
        "factors": {"spv.mode": ["grey", "depth"], "spv.num_phosphenes": [60, 240], "spv.overlays": [[], ["path"]]},
        "repetitions": 2, "subject_params": {"max_linear": 0.5}}))
    names = [c.name for c in s.protocol.conditions]
    assert len(names) == 8 and "mode=grey-num_phosphenes=60-overlays=none" in names
    assert s.protocol.condition("mode=depth-num_phosphenes=240-overlays=path").params == {
        "spv": {"mode": "depth", "num_phosphenes": 240, "overlays": ["path"]}}
    assert s.subjects == [1, 2, 3] and s.policy == "wander_avoid" and s.subject_params == {"max_linear": 0.5}
    assert s.protocol.design.repetitions == 2 and s.protocol.name == "s"
    assert s.protocol.tasks[0].world.endswith("experiments/worlds/hallway.yaml")   # relative to the protocol


@pytest.mark.parametrize("change, expected", [
    ({"policy": "fly"}, "policy: 'fly' is not allowed"),
    ({"subjects": 0}, "subjects: expected a count"),
    ({"factors": {"spv.mode": ["warp"]}}, "conditions.mode=warp.spv.mode: 'warp' is not allowed"),
    ({"factors": {"mode": ["grey"]}}, "factors.mode: expected NODE.PARAM"),
    ({"subject_params": {"max_linear": 9.0}}, "subject_params.max_linear: 9.0 is out of range"),
    ({"tasks": ["nope"]}, "tasks: expected a list of the protocol's tasks (hallway)"),
    ({"extra": 1}, "extra: unknown key"),
])
def test_sweep_mistakes(tmp_path, change, expected):
    doc = {"protocol": str(EXPERIMENTS_DIR / "example.yaml"), "policy": "follow_path", "subjects": 2,
           "factors": {"spv.mode": ["grey", "depth"]}}
    doc.update(change)
    with pytest.raises(ProtocolError) as err:
        load_sweep(write(tmp_path, doc))
    assert len(err.value.errors) == 1 and expected in err.value.errors[0], err.value.errors
