"""Manhattan axes: the two horizontal dominant directions of a scene's vertical surfaces
(no ROS). Camera optical frame C.

With the up direction known, the normals of vertical surfaces lie in the horizontal plane;
their azimuths folded modulo 90° pile up at the building's orientation (walls, furniture
sides). The mode of that area-weighted folded histogram is the Manhattan orientation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raspv_perception.plane_fitting import cross3, histogram_peaks


@dataclass(frozen=True)
class HorizontalBasis:
    """Unit vectors in C spanning the horizontal plane: ``forward`` (the camera z axis
    projected), ``right`` = down × forward, and ``down`` = −up."""

    forward: np.ndarray
    right: np.ndarray
    down: np.ndarray

    @classmethod
    def from_up(cls, up: np.ndarray) -> "HorizontalBasis":
        down = -np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
        f = np.array([0.0, 0.0, 1.0]) - down[2] * down
        if np.linalg.norm(f) < 1e-6:
            f = np.array([0.0, -1.0, 0.0]) - down[1] * down
        f /= np.linalg.norm(f)
        return cls(f, cross3(down, f), down)

    def azimuth_deg(self, vectors: np.ndarray) -> np.ndarray:
        """Azimuth [deg, 0–360) of vectors (N, 3) about the up axis: 0 along ``forward``,
        90 along ``right``."""
        v = np.asarray(vectors)
        a = np.degrees(np.arctan2(v @ self.right.astype(v.dtype), v @ self.forward.astype(v.dtype)))
        return np.mod(a, 360.0)

    def direction(self, azimuth_deg: float) -> np.ndarray:
        """The horizontal unit vector in C at ``azimuth_deg``."""
        a = math.radians(azimuth_deg)
        return math.cos(a) * self.forward + math.sin(a) * self.right


@dataclass(frozen=True)
class ManhattanAxes:
    """``z``: dominant horizontal direction closest to the viewing direction; ``x`` = down × z;
    ``support``: area of vertical surface agreeing with them [m²]."""

    x: np.ndarray
    z: np.ndarray
    support: float


def manhattan_axes(basis: HorizontalBasis, azimuths_deg: np.ndarray, areas: np.ndarray,
                   min_area: float, bin_deg: float = 1.0) -> ManhattanAxes | None:
    """Manhattan axes from the azimuths [deg] and areas [m²] of vertical-surface samples;
    None when less than ``min_area`` of surface agrees on an orientation."""
    if len(azimuths_deg) == 0:
        return None
    folded = np.mod(azimuths_deg, 90.0)
    peaks = histogram_peaks(folded, areas, 0.0, 90.0, bin_deg, min_area, separation=10.0, circular=True)
    if not peaks:
        return None
    psi, support = peaks[0]
    if psi > 45.0:
        psi -= 90.0
    z = basis.direction(psi)
    x = cross3(basis.down, z)
    return ManhattanAxes(x, z, support)
