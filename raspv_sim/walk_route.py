"""Whether a walk's route can be walked: every leg over free floor (no rclpy).

The simulated camera goes where the route says, through anything in the way. A leg drawn
through a wall shows a blank wall filling the view at half a metre and then, one step later,
the room behind it — a jump no real camera makes (the shipped ``office_two_loops`` walked
through the open plan's east wall, and SLAM lost tracking there). So a route is checked
against the world's occupancy map (static bodies between the ankles and the head,
:func:`raspv_sim.occupancy_export.world_occupancy`; people move and are left out): every point
of every leg, the closing leg back to the first waypoint included, must be at least
``clearance`` from an occupied or unknown cell. A kidnap's carry is not a leg.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raspv_common.occupancy import OccupancyGrid

CLEARANCE = 0.1         # [m] from a leg to the nearest occupied cell (a doorway of 0.9 m leaves 0.45)


@dataclass(frozen=True)
class Obstruction:
    """The first place a leg (``start`` → ``end``, W metres) comes closer than the clearance to
    something: ``at`` (x, y) [m], ``distance`` [m] to it there."""

    start: tuple[float, float]
    end: tuple[float, float]
    at: tuple[float, float]
    distance: float

    def describe(self) -> str:
        return (f"the leg ({self.start[0]:g}, {self.start[1]:g}) -> ({self.end[0]:g}, {self.end[1]:g}) goes "
                f"{'through' if self.distance <= 0 else f'{100 * self.distance:.0f} cm from'} a wall or furniture "
                f"at ({self.at[0]:.2f}, {self.at[1]:.2f}); route it through a door")


def route_obstruction(waypoints, grid: OccupancyGrid, clearance: float = CLEARANCE) -> Obstruction | None:
    """The first obstructed leg of the closed route through ``waypoints`` ((x, y) in W), or None."""
    distance = grid.obstacle_distance(unknown_is_obstacle=True)
    points = [np.asarray(p, dtype=float) for p in waypoints]
    step = grid.resolution / 2
    for a, b in zip(points, points[1:] + points[:1]):
        n = int(np.ceil(np.linalg.norm(b - a) / step)) + 1
        xy = a + (b - a) * np.linspace(0.0, 1.0, n)[:, None]
        rc = grid.world_to_cell(xy)
        inside = grid.inside(rc)
        d = np.zeros(n, np.float32)                      # off the map counts as blocked
        d[inside] = distance[rc[inside, 0], rc[inside, 1]]
        if d.min() < clearance:
            i = int(np.argmin(d))
            return Obstruction((float(a[0]), float(a[1])), (float(b[0]), float(b[1])),
                               (float(xy[i, 0]), float(xy[i, 1])), float(d[i]))
    return None
