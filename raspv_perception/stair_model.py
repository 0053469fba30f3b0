"""A detected staircase as data (no ROS): what :mod:`raspv_perception.stairs` returns and
``raspv_msgs/StairDetection`` carries (:mod:`raspv_perception.stairs_msg`).

Frames: camera optical frame C (x right, y down, z forward); stair frame S: origin at the middle
of the first step's front edge (on the floor), y down (gravity), z horizontal into the stair
(walking direction), x = y × z. Metres.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import IntEnum

import numpy as np


class StairDirection(IntEnum):
    """Numbered as the constants of ``raspv_msgs/StairDetection``."""

    ASCENDING = 0
    DESCENDING = 1


@dataclass
class StairStep:
    """One step. ``height`` of its tread above the floor [m] (negative going down); ``depth``
    and ``width`` of the tread [m]; ``tread_corners`` (4, 3) in C, front edge first (front-left,
    front-right, back-right, back-left as seen walking into the stair); ``measured``: False
    when ``depth`` is the mean tread because this step's edges are not both visible."""

    index: int
    height: float
    depth: float
    width: float
    tread_corners: np.ndarray
    measured: bool = True


@dataclass
class Staircase:
    """A detected staircase: ``camera_from_stair`` C_T_S (4×4, maps S to C); ``riser``,
    ``tread``, ``width`` [m]; ``distance``: horizontal distance from the camera to the first
    step's front edge [m]; ``steps`` in order from the floor."""

    direction: StairDirection
    camera_from_stair: np.ndarray
    riser: float
    tread: float
    width: float
    distance: float
    steps: list[StairStep] = field(default_factory=list)

    def segments(self) -> np.ndarray:
        """The wireframe (M, 2, 3) in C the paper draws (Fig. 4, pink): every tread's outline
        and the risers' side edges."""
        segs = []
        for step in self.steps:
            c = step.tread_corners
            segs.extend([(c[i], c[(i + 1) % 4]) for i in range(4)])
        for below, above in zip([None] + self.steps[:-1], self.steps):
            # riser: from the front edge of the step below (or the floor) up/down to this tread
            front = above.tread_corners[:2]
            drop = self.camera_from_stair[:3, 1] * (above.height - (below.height if below else 0.0))
            base = front + drop                                # the front edge at the lower level
            segs.extend([(base[0], front[0]), (base[1], front[1]), (base[0], base[1])])
        return np.array(segs, dtype=np.float64).reshape(-1, 2, 3)

    def in_frame(self, new_from_camera: np.ndarray) -> "Staircase":
        """The same staircase seen from another camera pose: ``new_from_camera`` (4×4) maps this
        staircase's camera frame C to the new one (e.g. C_frame ← C_detection from two poses);
        ``distance`` stays the detection's."""
        T = np.asarray(new_from_camera, dtype=np.float64)
        R, t = T[:3, :3], T[:3, 3]
        steps = [replace(st, tread_corners=np.asarray(st.tread_corners, dtype=np.float64) @ R.T + t) for st in self.steps]
        return replace(self, camera_from_stair=T @ self.camera_from_stair, steps=steps)
