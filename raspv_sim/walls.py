"""Walls with door openings (and optional door leaves) as primitive boxes in W (metres)."""
from __future__ import annotations

import math

from raspv_sim.primitives import Part, SolidObject, shade
from raspv_sim.world_spec import FURNITURE_DEFAULT_COLOR, DoorOpening, WallSpec

LEAF_THICKNESS = 0.04   # m
LEAF_CLEARANCE = 0.01   # m, gap between the leaf and the opening's frame


def wall_solids(wall: WallSpec) -> list[SolidObject]:
    """The wall (solid pieces between the openings, lintels above them) and one door object per
    opening that has a leaf (named ``<wall>/door<j>``, class ``door``)."""
    L, t = wall.length, wall.thickness
    dx, dy = (wall.end[0] - wall.start[0]) / L, (wall.end[1] - wall.start[1]) / L
    yaw = math.atan2(dy, dx)

    def piece(s0: float, s1: float, z0: float, z1: float) -> Part:
        s = (s0 + s1) / 2
        return Part("box", (s1 - s0, t, z1 - z0), (wall.start[0] + dx * s, wall.start[1] + dy * s, (z0 + z1) / 2),
                    wall.color, yaw)

    parts: list[Part] = []
    cursor = -t / 2
    for door in wall.doors:
        a, b = door.at - door.width / 2, door.at + door.width / 2
        if a - cursor > 1e-6:
            parts.append(piece(cursor, a, 0.0, wall.height))
        if wall.height - door.height > 1e-3:
            parts.append(piece(a, b, door.height, wall.height))
        cursor = b
    if L + t / 2 - cursor > 1e-6:
        parts.append(piece(cursor, L + t / 2, 0.0, wall.height))
    out = [SolidObject(wall.name, wall.cls, tuple(parts), where=wall.where)] if parts else []
    for j, door in enumerate(wall.doors):
        if door.leaf is not None:
            out.append(SolidObject(f"{wall.name}/door{j}", "door", (door_leaf(wall, door, yaw),), where=wall.where))
    return out


def door_leaf(wall: WallSpec, door: DoorOpening, wall_yaw: float) -> Part:
    """The leaf of ``door``, hinged at one side of the opening and turned by ``door.leaf`` degrees."""
    dx, dy = math.cos(wall_yaw), math.sin(wall_yaw)
    hinge_s = door.at - door.width / 2 if door.hinge == "start" else door.at + door.width / 2
    hinge = (wall.start[0] + dx * hinge_s, wall.start[1] + dy * hinge_s)
    closed = wall_yaw if door.hinge == "start" else wall_yaw + math.pi
    # opening towards the wall's left turns a start-hinged leaf counter-clockwise, an end-hinged one clockwise
    sign = 1.0 if (door.swing == "left") == (door.hinge == "start") else -1.0
    leaf_yaw = closed + sign * math.radians(door.leaf or 0.0)
    width = door.width - 2 * LEAF_CLEARANCE
    cx = hinge[0] + math.cos(leaf_yaw) * (LEAF_CLEARANCE + width / 2)
    cy = hinge[1] + math.sin(leaf_yaw) * (LEAF_CLEARANCE + width / 2)
    height = door.height - LEAF_CLEARANCE
    return Part("box", (width, LEAF_THICKNESS, height), (cx, cy, height / 2),
                shade(FURNITURE_DEFAULT_COLOR["door"], 1.0), leaf_yaw)
