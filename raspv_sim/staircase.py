"""Straight staircases as primitive boxes in W (metres).

Local frame of a staircase: origin at the middle of the first step's front edge on the floor
(z = 0), x along the walking direction, y to the left. Ascending: solid steps i = 0..n-1 span
x ∈ [i·T, (i+1)·T] with tops at (i+1)·R; the last one extends into the top landing. Descending:
a well cut into the floor over x ∈ [0, n·T + landing], |y| ≤ width/2; step i = 1..n has its top
at −i·R over x ∈ [(i−1)·T, i·T], then the bottom landing at −n·R; walls line the well.
"""
from __future__ import annotations

import math

import numpy as np

from raspv_sim.primitives import LocalFrame, Part, SolidObject, shade
from raspv_sim.world_spec import StairSpec

WELL_WALL = 0.1     # m, thickness of the walls lining a descending well
BASE = 0.1          # m, slab under the lowest step of a descending staircase


def staircase_solid(spec: StairSpec) -> SolidObject:
    f = LocalFrame((spec.position[0], spec.position[1], 0.0), math.radians(spec.yaw))
    R, T, W, n = spec.riser, spec.tread, spec.width, spec.steps
    parts: list[Part] = []
    if spec.direction == "up":
        for i in range(n):
            x0, x1 = i * T, (i + 1) * T + (spec.landing if i == n - 1 else 0.0)
            top = (i + 1) * R
            parts.append(f.box(((x0 + x1) / 2, 0, top / 2), (x1 - x0, W, top), shade(spec.color, 1.0 - 0.03 * (i % 2))))
    else:
        bottom = -n * R - BASE
        for i in range(1, n + 1):
            x0, x1 = (i - 1) * T, i * T
            top = -i * R
            parts.append(f.box(((x0 + x1) / 2, 0, (top + bottom) / 2), (T, W, top - bottom),
                               shade(spec.color, 1.0 - 0.03 * (i % 2))))
        if spec.landing > 0:
            x0, x1 = n * T, spec.run
            parts.append(f.box(((x0 + x1) / 2, 0, (-n * R + bottom) / 2), (x1 - x0, W, -n * R - bottom), spec.color))
        wall_color = shade(spec.color, 0.85)
        length = spec.run + WELL_WALL
        for side in (-1, 1):
            parts.append(f.box((length / 2, side * (W / 2 + WELL_WALL / 2), bottom / 2), (length, WELL_WALL, -bottom), wall_color))
        parts.append(f.box((spec.run + WELL_WALL / 2, 0, bottom / 2), (WELL_WALL, W, -bottom), wall_color))
    return SolidObject(spec.name, spec.cls, tuple(parts), where=spec.where)


def floor_hole(spec: StairSpec) -> tuple[float, float, float, float] | None:
    """The axis-aligned rectangle (x0, y0, x1, y1) in W that a descending staircase cuts out of the
    floor (including its lining walls), or None for an ascending one."""
    if spec.direction != "down":
        return None
    f = LocalFrame((spec.position[0], spec.position[1], 0.0), math.radians(spec.yaw))
    hw = spec.width / 2 + WELL_WALL
    corners = np.array([f.point(x, y, 0.0)[:2] for x in (0.0, spec.run + WELL_WALL) for y in (-hw, hw)])
    x0, y0 = corners.min(axis=0)
    x1, y1 = corners.max(axis=0)
    return float(x0), float(y0), float(x1), float(y1)

