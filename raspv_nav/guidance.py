"""What the navigation assistant tells the subject (no rclpy).

:class:`Guidance` gathers, for one control step, what the cues need — in the world frame W of
the poses (x, y on the floor, metres):

- ``next_waypoint``: the point ``lookahead`` m along the global path from the subject (the
  direction to walk; the guidance overlay's marker and the audio beacon point at it);
- the DWA suggestion (``linear``, ``angular``; ``feasible`` False: stop);
- ``nearest_obstacle``: the closest obstacle cell (static map or camera) within
  ``proximity_range`` m inside a cone of ``proximity_cone_deg`` around the walking direction —
  walls beside a corridor do not count, a person or a wall ahead does.

It travels as ``raspv_msgs/NavGuidance`` on ``/nav/guidance``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raspv_common.occupancy import OccupancyGrid


@dataclass
class Guidance:
    stamp: float                          # data time of the pose it was computed from [s]
    has_path: bool
    goal_reached: bool
    reason: str                           # why there is no path ("" otherwise)
    position: np.ndarray                  # (2,) the subject, W [m]
    heading: float                        # the subject's walking direction, W [rad]
    next_waypoint: np.ndarray | None      # (2,) W [m]
    distance_to_goal: float               # along the path [m] (straight line without a path)
    linear: float                         # DWA suggestion [m/s]
    angular: float                        # [rad/s]
    feasible: bool
    nearest_obstacle: np.ndarray | None   # (2,) W [m]
    nearest_obstacle_distance: float      # [m], inf when none


def nearest_obstacle_ahead(obstacles: np.ndarray, grid: OccupancyGrid, position: np.ndarray, heading: float,
                           max_range: float, cone_deg: float) -> tuple[np.ndarray | None, float]:
    """Centre of the obstacle cell (``obstacles`` bool on ``grid``) nearest to ``position``
    within ``max_range`` m and ±``cone_deg``/2 of ``heading`` [rad], and its distance."""
    rc = grid.world_to_cell(position)[0]
    k = int(math.ceil(max_range / grid.resolution))
    r0, c0 = max(0, rc[0] - k), max(0, rc[1] - k)
    rr, cc = np.nonzero(obstacles[r0:rc[0] + k + 1, c0:rc[1] + k + 1])
    if not len(rr):
        return None, math.inf
    pts = grid.cell_to_world(np.column_stack([rr + r0, cc + c0]))
    rel = pts - position
    dist = np.hypot(rel[:, 0], rel[:, 1])
    bearing = np.arctan2(rel[:, 1], rel[:, 0]) - heading
    off = np.abs(np.mod(bearing + math.pi, 2 * math.pi) - math.pi)
    ok = (dist <= max_range) & ((off <= math.radians(cone_deg) / 2) | (dist < grid.resolution))
    if not ok.any():
        return None, math.inf
    i = int(np.argmin(np.where(ok, dist, np.inf)))
    return pts[i], float(dist[i])
