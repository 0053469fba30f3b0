"""The phosphenes the subject sees, placed in the scene (no ROS).

Each displayed phosphene i at (x_i, y_i) px of the phosphene image I lies on the ray
K_P⁻¹·(x_i, y_i, 1) of the prosthesis camera, which looks along the camera optical frame C
(K_P: f_P = w / (2 tan(FOV/2)), c = (w/2, h/2), docs/spv.md). The marker draws every phosphene
that is not dropped as a sphere on the plane z = ``distance`` in front of the camera, as wide as
the phosphene's angular size at that distance, green by its displayed brightness: a screen
floating in front of the camera, like RViz's camera display.
"""
from __future__ import annotations

import numpy as np

from raspv_viz.shapes import SPHERE_LIST, MarkerShape, transform_points

MIN_ALPHA = 0.15   # a phosphene at brightness 0 stays faintly visible, so the layout shows


def phosphene_points(x_px: np.ndarray, y_px: np.ndarray, width: int, height: int, focal_px: float,
                     distance: float) -> np.ndarray:
    """(N, 3) points in C of phosphenes at (x, y) px of a w×h phosphene image, on z = ``distance``."""
    x = np.asarray(x_px, dtype=np.float64)
    y = np.asarray(y_px, dtype=np.float64)
    scale = distance / float(focal_px)
    return np.column_stack([(x - width / 2.0) * scale, (y - height / 2.0) * scale, np.full(len(x), float(distance))])


def phosphene_marker(x_px: np.ndarray, y_px: np.ndarray, brightness: np.ndarray, dropped: np.ndarray,
                     width: int, height: int, focal_px: float, diameter_px: float, distance: float,
                     T: np.ndarray) -> list[MarkerShape]:
    """One sphere list (namespace ``phosphenes``) of the phosphenes not dropped; brightness 0..1
    per phosphene; ``T``: · ← C."""
    keep = ~np.asarray(dropped, dtype=bool)
    if not keep.any():
        return []
    pts = transform_points(T, phosphene_points(np.asarray(x_px)[keep], np.asarray(y_px)[keep], width, height,
                                               focal_px, distance))
    b = np.clip(np.asarray(brightness, dtype=np.float64)[keep], 0.0, 1.0)
    colors = np.column_stack([0.2 * b, b, 0.2 * b, MIN_ALPHA + (1.0 - MIN_ALPHA) * b])
    size = float(diameter_px) / float(focal_px) * distance
    return [MarkerShape("phosphenes", 0, SPHERE_LIST, (0.0, 1.0, 0.0, 1.0), (size, size, size), points=pts,
                        colors=colors)]
