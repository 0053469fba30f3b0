"""Obstacle-free floor in the floor frame F (no ROS).

A grid over the floor (x, z in F, metres) marks cells where floor was seen and cells covered by
an obstacle's footprint grown by a safety margin. Floor cells not covered are free; the largest
free region, outlined, is the free-floor polygon.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np


@dataclass
class FreeFloor:
    """``blocked`` (rows, cols) bool grid of cells covered by obstacles (with margin); cell
    (r, c) spans x ∈ [x0 + c·cell, …), z ∈ [r·cell, …). ``polygon`` (M, 2) (x, z) in F of the
    largest free region, empty when there is none."""

    cell: float
    x0: float
    blocked: np.ndarray
    polygon: np.ndarray

    def is_blocked(self, xz: np.ndarray) -> np.ndarray:
        """True for floor points (N, 2) (x, z in F) inside a blocked cell."""
        xz = np.asarray(xz, dtype=np.float64).reshape(-1, 2)
        rows, cols = self.blocked.shape
        c = np.floor((xz[:, 0] - self.x0) / self.cell).astype(np.int64)
        r = np.floor(xz[:, 1] / self.cell).astype(np.int64)
        inside = (c >= 0) & (c < cols) & (r >= 0) & (r < rows)
        out = np.zeros(len(xz), dtype=bool)
        out[inside] = self.blocked[r[inside], c[inside]]
        return out


def free_floor(floor_xz: np.ndarray, obstacle_xz: np.ndarray, cell: float, margin: float, reach: float) -> FreeFloor:
    """Free floor from floor points (N, 2) and obstacle points (M, 2), both (x, z) in F [m].

    ``reach`` bounds the grid (|x| ≤ reach, 0 ≤ z ≤ reach) [m]; ``margin`` grows obstacle
    footprints [m]. The polygon outlines the largest connected free region (small gaps between
    sparse far floor samples closed first), simplified to ``cell`` accuracy.
    """
    cols = int(math.ceil(2 * reach / cell))
    rows = int(math.ceil(reach / cell))
    x0 = -reach

    def raster(xz: np.ndarray) -> np.ndarray:
        grid = np.zeros((rows, cols), dtype=np.uint8)
        xz = np.asarray(xz, dtype=np.float64).reshape(-1, 2)
        c = np.floor((xz[:, 0] - x0) / cell).astype(np.int64)
        r = np.floor(xz[:, 1] / cell).astype(np.int64)
        ok = (c >= 0) & (c < cols) & (r >= 0) & (r < rows)
        grid[r[ok], c[ok]] = 1
        return grid

    seen = raster(floor_xz)
    obstacles = raster(obstacle_xz)
    radius = int(math.ceil(margin / cell))
    if radius > 0 and obstacles.any():
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
        blocked = cv2.dilate(obstacles, kernel)
    else:
        blocked = obstacles
    seen = cv2.morphologyEx(seen, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    free = seen & (1 - blocked)
    polygon = np.zeros((0, 2))
    # Labels without OpenCV's statistics (which cost 4x the labelling); areas by counting.
    count, comp = cv2.connectedComponents(free, connectivity=8)
    if count > 1:
        biggest = 1 + int(np.argmax(np.bincount(comp.reshape(-1), minlength=count)[1:]))
        region = (comp == biggest).astype(np.uint8)
        contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        if contours:
            contour = max(contours, key=cv2.contourArea)
            contour = cv2.approxPolyDP(contour, 1.0, True).reshape(-1, 2).astype(np.float64)
            polygon = np.stack([x0 + (contour[:, 0] + 0.5) * cell, (contour[:, 1] + 0.5) * cell], axis=1)
    return FreeFloor(cell, x0, blocked.astype(bool), polygon)
