"""A world's 2-D occupancy map for planners (map_server PGM + YAML via :mod:`raspv_common.occupancy`).

A cell (``resolution`` m square, W frame, row 0 at the smallest y) is

- **occupied** when a static object's collision geometry enters the cell's column between
  ``band`` = (lowest, highest) heights above the floor [m] — walls, furniture, models and
  staircases; people are left out (they move) — or when there is no floor within ±``band[0]``
  of z = 0 under the cell's centre (a stair well, the edge of the floor);
- **free** otherwise, inside the floor rectangle; **unknown** in the border around it.

The column test is exact for any shape (a box probe per cell against PyBullet's collision
geometry), limited to the cells inside each link's bounding box. With ``structure_only`` only
walls, doors and stairs count, as the paper's building map ("structural and permanent elements";
furniture is left to the camera).
"""
from __future__ import annotations

import math

import numpy as np
import pybullet

from raspv_common.occupancy import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from raspv_sim.world_builder import BuiltWorld

BORDER = 0.5          # m of unknown cells around the floor
RAY_BATCH = 16000     # PyBullet's limit for one rayTestBatch is 16384
MAX_CELLS = 20_000_000


def world_occupancy(world: BuiltWorld, resolution: float = 0.05, band: tuple[float, float] = (0.05, 1.9),
                    structure_only: bool = False) -> OccupancyGrid:
    """Occupancy grid of ``world`` (static bodies) at ``resolution`` m per cell."""
    if not resolution > 0:
        raise ValueError(f"map resolution must be positive, got {resolution}")
    lo_z, hi_z = band
    if not 0 < lo_z < hi_z:
        raise ValueError(f"height band must satisfy 0 < low < high, got {band}")
    c = world.client
    floor = world.spec.floor
    x0, y0 = floor.lo[0] - BORDER, floor.lo[1] - BORDER
    cols = int(math.ceil((floor.hi[0] + BORDER - x0) / resolution))
    rows = int(math.ceil((floor.hi[1] + BORDER - y0) / resolution))
    xs = x0 + (np.arange(cols) + 0.5) * resolution
    ys = y0 + (np.arange(rows) + 0.5) * resolution
    if rows * cols > MAX_CELLS:
        raise ValueError(f"a {cols}x{rows} map at {resolution} m per cell is too large (at most {MAX_CELLS} cells); "
                         "use a coarser resolution")
    cells = np.full((rows, cols), UNKNOWN, np.int8)
    inside = ((ys[:, None] > floor.lo[1]) & (ys[:, None] < floor.hi[1]) & (xs[None, :] > floor.lo[0])
              & (xs[None, :] < floor.hi[0]))
    cells[inside] = FREE

    # no floor near z = 0 under the cell centre → a drop
    rr, cc = np.nonzero(inside)
    starts = np.stack([xs[cc], ys[rr], np.full(rr.size, lo_z)], axis=1)
    ends = starts.copy()
    ends[:, 2] = -lo_z
    ground = np.zeros(rr.size, bool)
    for i in range(0, rr.size, RAY_BATCH):
        hits = c.rayTestBatch(starts[i:i + RAY_BATCH].tolist(), ends[i:i + RAY_BATCH].tolist())
        ground[i:i + RAY_BATCH] = [h[0] >= 0 for h in hits]
    cells[rr[~ground], cc[~ground]] = OCCUPIED

    # objects in the column band, probed per cell inside each link's bounding box
    half = [resolution / 2, resolution / 2, (hi_z - lo_z) / 2]
    probe = c.createMultiBody(0, c.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half), -1,
                              basePosition=[0, 0, -100])
    c.setCollisionFilterGroupMask(probe, -1, 0, 0)
    zc = (lo_z + hi_z) / 2
    try:
        for uid in world.static_uids(structure_only):
            if world.bodies[uid].cls == "floor":
                continue
            for link in range(-1, c.getNumJoints(uid)):
                amin, amax = c.getAABB(uid, link)
                if amax[2] <= lo_z or amin[2] >= hi_z or amax[0] - amin[0] <= 0:
                    continue
                c0 = max(0, int(math.floor((amin[0] - x0) / resolution)))
                c1 = min(cols - 1, int(math.floor((amax[0] - x0) / resolution)))
                r0 = max(0, int(math.floor((amin[1] - y0) / resolution)))
                r1 = min(rows - 1, int(math.floor((amax[1] - y0) / resolution)))
                for r in range(r0, r1 + 1):
                    for col in range(c0, c1 + 1):
                        if cells[r, col] == OCCUPIED:
                            continue
                        c.resetBasePositionAndOrientation(probe, [xs[col], ys[r], zc], [0, 0, 0, 1])
                        if c.getClosestPoints(probe, uid, 0.0, -1, link):
                            cells[r, col] = OCCUPIED
    finally:
        c.removeBody(probe)
    return OccupancyGrid(cells, float(resolution), (float(x0), float(y0)))
