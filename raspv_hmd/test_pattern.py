"""A phosphene-like test image for the headset benchmark, the reference client's self-test and
the bridge's tests: Gaussian dots on a hexagonal lattice (the paper's default device, 1000
phosphenes, 8 levels, 800×800), whose levels follow a bar sweeping across the view, so
consecutive frames differ and a viewer sees motion. Not a phosphene model — that is raspv_spv.
"""
from __future__ import annotations

import math

import cv2
import numpy as np


class PhospheneTestPattern:
    """Frames of ``width`` × ``height`` px mono8; :meth:`frame` (t in s) costs a few ms at 800×800."""

    def __init__(self, width: int = 800, height: int = 800, count: int = 1000, levels: int = 8,
                 period_s: float = 2.0) -> None:
        if width < 8 or height < 8 or count < 1 or levels < 2 or period_s <= 0:
            raise ValueError("test pattern needs width, height >= 8, count >= 1, levels >= 2, period_s > 0")
        self.width, self.height, self.levels, self.period_s = width, height, levels, period_s
        dx = max(2, int(math.sqrt(width * height * (2 / math.sqrt(3)) / count)))
        dy = max(2, int(math.sqrt(3) / 2 * dx))
        xs, ys = [], []
        for row, y in enumerate(range(dy // 2, height, dy)):
            for x in range(dx // 2 + (dx // 2 if row % 2 else 0), width, dx):
                xs.append(x)
                ys.append(y)
        self.x = np.array(xs)
        self.y = np.array(ys)
        size = dx | 1                                      # odd sprite width ≈ the lattice spacing
        sigma = size / 6.3                                 # the sprite falls to ~1 % at its border
        g = cv2.getGaussianKernel(size, sigma).astype(np.float32)
        self._kernel_1d = g / g.max()            # separable sprite with peak 1
        self._impulses = np.zeros((height, width), np.float32)
        scatter = (np.arange(len(xs)) * 2654435761) % 97          # a fixed scatter of dim steady dots
        self._steady = np.where(scatter < 12, 2, 0)

    def frame(self, t: float) -> np.ndarray:
        """The pattern at time ``t`` [s]: a bright bar moving left → right once per period."""
        phase = (t / self.period_s) % 1.0
        centre = phase * self.width
        dist = np.abs(self.x - centre) / (0.15 * self.width)
        level = np.clip(np.round((self.levels - 1) * (1.0 - dist)), 0, self.levels - 1)
        level = np.maximum(level, self._steady)
        self._impulses[self.y, self.x] = level / (self.levels - 1)
        out = cv2.sepFilter2D(self._impulses, -1, self._kernel_1d, self._kernel_1d, borderType=cv2.BORDER_CONSTANT)
        return np.clip(out * 255.0, 0.0, 255.0).astype(np.uint8)
