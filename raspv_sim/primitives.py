"""Primitive solids (boxes, cylinders, spheres, capsules) that world objects are built from.

Pure geometry, no pybullet: builders return :class:`Part` lists in the world frame W (metres,
z up), and :mod:`raspv_sim.world_builder` turns them into PyBullet bodies.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

RGB = tuple[float, float, float]


@dataclass(frozen=True)
class Part:
    """One solid. ``shape`` is "box" (``size`` = full extents x, y, z), "cylinder" / "capsule"
    (``size`` = (diameter, diameter, length along z)) or "sphere" (``size`` = diameter ×3).
    ``position`` is its centre in W [m]; ``yaw`` [rad] turns it about z."""

    shape: str
    size: tuple[float, float, float]
    position: tuple[float, float, float]
    color: RGB
    yaw: float = 0.0
    collide: bool = True
    visible: bool = True

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        """Orientation (x, y, z, w) about z."""
        return (0.0, 0.0, math.sin(self.yaw / 2), math.cos(self.yaw / 2))


class LocalFrame:
    """Places parts given in an object's local frame (x forward, y left, z up; origin on its base)
    at ``position`` (W, m) turned by ``yaw`` [rad]."""

    def __init__(self, position: tuple[float, float, float], yaw: float):
        self.origin = np.asarray(position, dtype=float)
        self.yaw = float(yaw)
        self.c, self.s = math.cos(yaw), math.sin(yaw)

    def point(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        return (float(self.origin[0] + self.c * x - self.s * y), float(self.origin[1] + self.s * x + self.c * y),
                float(self.origin[2] + z))

    def box(self, center: tuple[float, float, float], size: tuple[float, float, float], color: RGB,
            yaw: float = 0.0, **kw) -> Part:
        return Part("box", tuple(float(v) for v in size), self.point(*center), color, self.yaw + yaw, **kw)

    def cylinder(self, center: tuple[float, float, float], diameter: float, length: float, color: RGB, **kw) -> Part:
        return Part("cylinder", (diameter, diameter, length), self.point(*center), color, self.yaw, **kw)

    def sphere(self, center: tuple[float, float, float], diameter: float, color: RGB, **kw) -> Part:
        return Part("sphere", (diameter, diameter, diameter), self.point(*center), color, self.yaw, **kw)

    def capsule(self, center: tuple[float, float, float], diameter: float, length: float, color: RGB, **kw) -> Part:
        return Part("capsule", (diameter, diameter, length), self.point(*center), color, self.yaw, **kw)


def shade(color: RGB, factor: float) -> RGB:
    """``color`` scaled by ``factor`` (clipped to [0, 1])."""
    return tuple(float(min(1.0, max(0.0, c * factor))) for c in color)  # type: ignore[return-value]


@dataclass(frozen=True)
class SolidObject:
    """A named, labelled world object made of parts (one PyBullet body). ``specular`` marks shiny
    surfaces the optional depth-sensor model drops readings on."""

    name: str
    cls: str
    parts: tuple[Part, ...]
    specular: bool = False
    where: str = ""
