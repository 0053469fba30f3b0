"""What a virtual patient is told of the goal, a protocol's choice (raspv_experiments/goal_knowledge.py):
the exact position, a noisy direction without a distance, or nothing — the same in quick trials
and in the graph's instructions (the session runner calls the same function with the same seed)."""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from raspv_experiments.goal_knowledge import DIRECTION_DISTANCE_M, GoalKnowledge, told_goal
from raspv_experiments.protocol import ProtocolError, load_protocol
from raspv_experiments.quick_trial import quick_trial

from .conftest import REPO

HALLWAY = str(REPO / "experiments" / "worlds" / "hallway.yaml")
SPV = {"device": "argus_ii", "mode": "depth", "temporal": False, "max_depth": 3.0}


def test_exact_direction_and_none():
    goal = (7.6, -0.6)
    assert told_goal(goal, GoalKnowledge(), 5) == goal
    assert told_goal(goal, GoalKnowledge("none"), 5) is None
    bearings = []
    for seed in range(400):
        x, y = told_goal(goal, GoalKnowledge("direction", 20.0), seed)
        assert math.hypot(x, y) == pytest.approx(DIRECTION_DISTANCE_M)           # no distance is told
        bearings.append(math.degrees(math.atan2(y, x) - math.atan2(goal[1], goal[0])))
    assert abs(np.mean(bearings)) < 3.0 and 17.0 < np.std(bearings) < 23.0        # the stated error
    assert told_goal(goal, GoalKnowledge("direction", 20.0), 9) == told_goal(goal, GoalKnowledge("direction", 20.0), 9)
    assert told_goal(goal, GoalKnowledge("direction", 0.0), 9) == pytest.approx(
        (DIRECTION_DISTANCE_M * math.cos(math.atan2(-0.6, 7.6)), DIRECTION_DISTANCE_M * math.sin(math.atan2(-0.6, 7.6))))


def test_a_protocol_chooses_it_and_a_mistake_is_one_line(tmp_path, example_doc, write_protocol):
    assert load_protocol(write_protocol(example_doc)).goal_knowledge == GoalKnowledge()
    example_doc["goal_knowledge"] = {"told": "direction", "direction_noise_deg": 15}
    assert load_protocol(write_protocol(example_doc)).goal_knowledge == GoalKnowledge("direction", 15.0)
    example_doc["goal_knowledge"] = {"told": "roughly"}
    with pytest.raises(ProtocolError) as info:
        load_protocol(write_protocol(example_doc))
    assert info.value.errors == [f"{tmp_path / 'protocol.yaml'}: goal_knowledge.told: expected one of exact, "
                                 "direction, none, got 'roughly'"]


def test_a_patient_told_nothing_walks_on_as_it_started():
    """From the hallway's start facing along it, with the goal behind: told the goal, the patient
    turns round; told nothing, it walks on down the hallway."""
    from raspv_experiments.policies import PolicyConfig

    config = PolicyConfig(seed=1, reaction_time_s=0.0, noise=0.0)
    told = quick_trial(HALLWAY, (5.0, 1.5, 0.0), (1.0, 1.5, 0.8), 4.0, spv=SPV, config=config)
    untold = quick_trial(HALLWAY, (5.0, 1.5, 0.0), (1.0, 1.5, 0.8), 4.0, spv=SPV, config=config,
                         goal_knowledge=GoalKnowledge("none"))
    assert told.path[-1][0] < 5.0 < untold.path[-1][0] - 0.5, (told.path[-1], untold.path[-1])
