"""Edges: Canny on the grey image or on the depth image, at full level (paper §III-C1).

Canny edges are one camera pixel thin while phosphenes are several camera pixels apart, so a
phosphene lights when an edge crosses the square of one phosphene spacing around its camera
pixel (box sums on an integral image), not only when it hits the single pixel.
"""
from __future__ import annotations

import cv2
import numpy as np

from raspv_spv.modes.base import Mode
from raspv_spv.sampling import Sampling


def edge_integral(edges: np.ndarray) -> np.ndarray:
    """Integral image (H+1, W+1) int32 of the edge pixels of ``edges`` (nonzero = edge)."""
    return cv2.integral((edges > 0).astype(np.uint8))


def edges_near(integral: np.ndarray, sampling: Sampling) -> np.ndarray:
    """(N,) bool: some edge pixel lies within half a phosphene spacing of each phosphene's
    camera pixel (False outside the camera); ``integral`` from :func:`edge_integral`."""
    h, w = integral.shape[0] - 1, integral.shape[1] - 1
    s = sampling.for_shape(h, w)
    half = max(0, int(round(s.spacing_camera_px / 2.0)))
    r0 = np.clip(s.rows - half, 0, h)
    r1 = np.clip(s.rows + half + 1, 0, h)
    c0 = np.clip(s.cols - half, 0, w)
    c1 = np.clip(s.cols + half + 1, 0, w)
    count = integral[r1, c1] - integral[r0, c1] - integral[r1, c0] + integral[r0, c0]
    return (count > 0) & s.inside


class EdgesMode(Mode):
    """Canny (``edge_low``, ``edge_high`` thresholds) on the grey image."""

    name = "edges"
    description = "Canny edges of the grey image"
    needs = frozenset({"color", "camera"})
    defaults = {"edge_low": 50.0, "edge_high": 150.0}

    def edges(self, inputs) -> np.ndarray:
        grey = cv2.cvtColor(np.ascontiguousarray(inputs.color), cv2.COLOR_RGB2GRAY)
        return cv2.Canny(grey, float(self.settings["edge_low"]), float(self.settings["edge_high"]))

    def levels(self, inputs, sampling, num_levels):
        key = (self.name, self.settings["edge_low"], self.settings["edge_high"])
        integral = inputs.cached(key, lambda: edge_integral(self.edges(inputs)))
        return np.where(edges_near(integral, sampling), num_levels - 1, 0).astype(np.uint8)


class DepthEdgesMode(Mode):
    """Canny on depth scaled to 8 bits over [0, ``max_depth``] m (farther saturates). Edges
    next to missing depth are dropped, so sensor holes do not draw outlines."""

    name = "edges_depth"
    description = "Canny edges of the depth image (depth discontinuities)"
    needs = frozenset({"depth", "camera"})
    defaults = {"edge_low": 50.0, "edge_high": 150.0, "max_depth": 3.0}

    def edges(self, inputs) -> np.ndarray:
        depth = np.asarray(inputs.depth, dtype=np.float32)
        invalid = ~np.isfinite(depth) | (depth <= 0)
        scaled = np.where(invalid, 0.0, np.minimum(depth, self.settings["max_depth"]) * (255.0 / self.settings["max_depth"]))
        edges = cv2.Canny(scaled.astype(np.uint8), float(self.settings["edge_low"]), float(self.settings["edge_high"]))
        if invalid.any():
            near_hole = cv2.dilate(invalid.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
            edges[near_hole] = 0
        return edges

    def levels(self, inputs, sampling, num_levels):
        key = (self.name, self.settings["edge_low"], self.settings["edge_high"], self.settings["max_depth"])
        integral = inputs.cached(key, lambda: edge_integral(self.edges(inputs)))
        return np.where(edges_near(integral, sampling), num_levels - 1, 0).astype(np.uint8)
