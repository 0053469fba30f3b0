"""What a virtual patient is told about the goal — a protocol's choice (no rclpy).

``goal_knowledge: {told: exact | direction | none, direction_noise_deg: 30}`` in a protocol:

- ``exact`` (the default): the goal's position from the start (x ahead, y left [m]), as before;
- ``direction``: only a direction, as a person told "the door is ahead on the left" — the goal's
  bearing from the start with a Gaussian error of ``direction_noise_deg`` (seeded per trial:
  the same subject and trial, the same error), and no distance: the subject is given a point
  :data:`DIRECTION_DISTANCE_M` along it and walks until the goal region is reached;
- ``none``: nothing (exploring): the subject walks on as it started.

The same function serves the graph (the session runner's instructions) and ``quick_trial``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

KINDS = ("exact", "direction", "none")
DIRECTION_DISTANCE_M = 30.0          # a direction without a distance: a point this far along it [m]


@dataclass(frozen=True)
class GoalKnowledge:
    told: str = "exact"                  # one of KINDS
    direction_noise_deg: float = 30.0    # standard deviation of the told bearing's error [deg]


def told_goal(goal_from_start: tuple[float, float], knowledge: GoalKnowledge,
              trial_seed: int) -> tuple[float, float] | None:
    """What the subject is told: the goal from the start (x ahead, y left [m]) as ``knowledge``
    says, the direction's error drawn from ``trial_seed`` (the subject's seed of the trial)."""
    if knowledge.told == "exact":
        return (float(goal_from_start[0]), float(goal_from_start[1]))
    if knowledge.told == "none":
        return None
    if knowledge.told != "direction":
        raise ValueError(f"goal_knowledge.told: {knowledge.told!r}; expected one of {', '.join(KINDS)}")
    error = math.radians(np.random.default_rng([int(trial_seed), 7]).normal(0.0, knowledge.direction_noise_deg))
    bearing = math.atan2(goal_from_start[1], goal_from_start[0]) + error
    return (DIRECTION_DISTANCE_M * math.cos(bearing), DIRECTION_DISTANCE_M * math.sin(bearing))
