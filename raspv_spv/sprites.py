"""Phosphene sprites (paper Appendix A-A): the reference spot S_r of one phosphene, no ROS.

A sprite is a function of the offset (dx, dy) [px] from the phosphene centre, 1 at full
brightness, 0 outside ``radius_px``. The renderer samples it once per pixel when the map is
built, so any shape costs the same per frame. Level i of N_L displays S_i = i/(N_L−1)·S_r.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np


class Sprite(ABC):
    """A phosphene's brightness profile around its centre."""

    @property
    @abstractmethod
    def radius_px(self) -> float:
        """No pixel farther than this from the centre is lit."""

    @abstractmethod
    def weights(self, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
        """Brightness in [0, 1] at offsets (dx, dy) px from the centre (any matching shapes)."""


@dataclass(frozen=True)
class GaussianSprite(Sprite):
    """Round Gaussian spot as in the authors' code: drawn ``draw_scale``·φ px wide (an integer
    number of pixels), falling to ``border_value`` at the border of that square
    (σ ≈ 4.6 px for the default φ = 19.8 px), and cut to the disc inside it."""

    diameter_px: float
    draw_scale: float = 1.5
    border_value: float = 0.01

    def __post_init__(self) -> None:
        if not (math.isfinite(self.diameter_px) and self.diameter_px > 0):
            raise ValueError(f"phosphene diameter must be positive, got {self.diameter_px} px")
        if not 0 < self.border_value < 1:
            raise ValueError(f"border value must be in (0, 1), got {self.border_value}")

    @property
    def size_px(self) -> int:
        """Width of the drawn square, px."""
        return max(1, int(self.draw_scale * self.diameter_px))

    @property
    def radius_px(self) -> float:
        return (self.size_px - 1) / 2.0

    @property
    def sigma_px(self) -> float:
        r = self.radius_px
        return r / math.sqrt(2.0 * math.log(1.0 / self.border_value)) if r > 0 else 0.0

    def weights(self, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
        d2 = np.asarray(dx, dtype=np.float64) ** 2 + np.asarray(dy, dtype=np.float64) ** 2
        r = self.radius_px
        if r < 0.5:                                   # sub-pixel phosphene: one lit pixel
            return (d2 <= 0.25).astype(np.float64)
        return np.where(d2 <= r * r, np.exp(-d2 / (2.0 * self.sigma_px ** 2)), 0.0)


@dataclass(frozen=True)
class BitmapSprite(Sprite):
    """Any shape (e.g. an elongated or doughnut phosphene) given as a square image with values
    in [0, 1], drawn ``draw_scale``·φ px wide and sampled bilinearly."""

    image: np.ndarray = field(repr=False)
    diameter_px: float = 20.0
    draw_scale: float = 1.5

    def __post_init__(self) -> None:
        img = np.asarray(self.image, dtype=np.float64)
        if img.ndim != 2 or img.shape[0] != img.shape[1] or img.shape[0] < 2:
            raise ValueError(f"sprite bitmap must be a square 2-D image, got shape {img.shape}")
        if not np.all(np.isfinite(img)) or img.min() < 0 or img.max() > 1:
            raise ValueError("sprite bitmap values must be finite and in [0, 1]")
        if not (math.isfinite(self.diameter_px) and self.diameter_px > 0):
            raise ValueError(f"phosphene diameter must be positive, got {self.diameter_px} px")

    @property
    def radius_px(self) -> float:
        return self.draw_scale * self.diameter_px / 2.0

    def weights(self, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
        from scipy.ndimage import map_coordinates   # only bitmap sprites need it (slow import)

        img = np.asarray(self.image, dtype=np.float64)
        n = img.shape[0]
        scale = n / (2.0 * self.radius_px)            # bitmap px per image px
        dx = np.asarray(dx, dtype=np.float64)
        dy = np.asarray(dy, dtype=np.float64)
        cols = dx * scale + (n - 1) / 2.0
        rows = dy * scale + (n - 1) / 2.0
        out = map_coordinates(img, [rows.ravel(), cols.ravel()], order=1, mode="constant", cval=0.0)
        return np.clip(out, 0.0, 1.0).reshape(dx.shape)
