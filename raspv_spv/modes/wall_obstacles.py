"""Wall-Obstacles (paper §IV-A2): walls at half level, horizontal planes (tables, seats,
steps) and obstacle clusters at full level, floor and everything else off — read from each
phosphene's camera pixel in ``/scene/labels``."""
from __future__ import annotations

import numpy as np

from raspv_perception import scene_labels as L
from raspv_spv.modes.base import Mode, quantise


def wall_obstacle_levels(labels: np.ndarray, num_levels: int) -> np.ndarray:
    """(N,) levels from the scene classes (N,) of the phosphenes."""
    half = int(quantise(np.array([0.5]), num_levels)[0])
    out = np.zeros(labels.shape, dtype=np.uint8)
    out[labels == L.WALL] = half
    out[(labels == L.HORIZONTAL) | (labels == L.OBSTACLE)] = num_levels - 1
    return out


class WallObstaclesMode(Mode):
    name = "wall_obstacles"
    description = "walls half, horizontal planes and obstacles full, floor off"
    needs = frozenset({"scene_labels", "camera"})

    def levels(self, inputs, sampling, num_levels):
        return wall_obstacle_levels(sampling.sample(inputs.scene_labels, fill=L.NONE), num_levels)
