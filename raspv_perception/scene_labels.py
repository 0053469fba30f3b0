"""Per-pixel scene classes of ``/scene/labels`` (mono8, same size as the depth image).

Modes read a phosphene's class by looking up its camera pixel. Ids are stable (published).
``FLOOR`` is walkable floor; floor under or right next to an obstacle (or a table) is
``FLOOR_BLOCKED``, so "obstacle-free floor" is a single comparison.
"""
from __future__ import annotations

import numpy as np

NONE = 0            # no valid depth, or outside the processed range
FLOOR = 1           # obstacle-free floor
WALL = 2            # vertical plane large enough to be a wall
HORIZONTAL = 3      # upward-facing plane that is not the floor: table, seat, step (or the support plane without a floor)
OBSTACLE = 4        # Euclidean cluster of points that are neither floor nor wall, above the floor
OTHER = 5           # anything else measured: slanted or downward-facing planes, ceiling, small fragments
FLOOR_BLOCKED = 6   # floor under or within the safety margin of an obstacle

NAMES: dict[int, str] = {
    NONE: "none",
    FLOOR: "floor",
    WALL: "wall",
    HORIZONTAL: "horizontal",
    OBSTACLE: "obstacle",
    OTHER: "other",
    FLOOR_BLOCKED: "floor_blocked",
}

# Display colours (RGB) for figures and debugging views.
COLORS: dict[int, tuple[int, int, int]] = {
    NONE: (0, 0, 0),
    FLOOR: (60, 170, 60),
    WALL: (230, 200, 40),
    HORIZONTAL: (40, 110, 230),
    OBSTACLE: (220, 40, 40),
    OTHER: (150, 150, 150),
    FLOOR_BLOCKED: (30, 80, 30),
}


def colorize(labels):
    """(H, W) class ids → (H, W, 3) uint8 RGB using :data:`COLORS` (unknown ids black)."""
    lut = np.zeros((256, 3), dtype=np.uint8)
    for k, c in COLORS.items():
        lut[k] = c
    return lut[np.asarray(labels, dtype=np.uint8)]
