"""The *no-data* pattern: what the display shows while the camera is stale (no ROS).

A dotted ring along the border of the phosphene field — every other phosphene of the outermost
band, ~1.5 phosphene spacings deep — at full level, blinking at :data:`BLINK_HZ` (on half of each
period). Nothing a mode draws looks like it: modes follow the scene, this is fixed in the field
and blinks; an experimenter sees it on the monitor, a wearer learns it in one sentence ("a
blinking ring means the camera stopped"). The border follows the field's shape: for a
rectangular field the normalised distance from the centre is the Chebyshev one
(max(|x|/half-width, |y|/half-height)), for a circular field the Euclidean one; implant layouts
use their phosphenes' bounding box. Levels are precomputed (display thread: no allocation).
"""
from __future__ import annotations

import math

import numpy as np

BLINK_HZ = 2.0
BAND_SPACINGS = 1.5      # depth of the border band [phosphene spacings]


def ring_mask(display_centres: np.ndarray, dropped: np.ndarray, circular: bool) -> np.ndarray:
    """(N,) bool: the phosphenes of the dotted border ring (every other one around the centre)."""
    xy = np.asarray(display_centres, dtype=float)
    visible = ~np.asarray(dropped, dtype=bool)
    if xy.shape[0] == 0 or not visible.any():
        return np.zeros(xy.shape[0], bool)
    lo, hi = xy[visible].min(axis=0), xy[visible].max(axis=0)
    centre, half = (lo + hi) / 2.0, np.maximum((hi - lo) / 2.0, 1e-6)
    u = (xy - centre) / half
    radius = np.hypot(u[:, 0], u[:, 1]) if circular else np.abs(u).max(axis=1)
    # the lattice spacing in normalised units: the mean nearest distance for an even spread
    spacing = math.sqrt(4.0 / max(int(visible.sum()), 1))
    band = visible & (radius >= radius[visible].max() - BAND_SPACINGS * spacing)
    idx = np.flatnonzero(band)
    order = idx[np.argsort(np.arctan2(u[idx, 1], u[idx, 0]), kind="stable")]
    mask = np.zeros(xy.shape[0], bool)
    mask[order[::2]] = True
    return mask


class NoDataPattern:
    """Levels of the no-data pattern for a map at any time."""

    def __init__(self, display_centres: np.ndarray, dropped: np.ndarray, circular: bool, num_levels: int) -> None:
        self.mask = ring_mask(display_centres, dropped, circular)
        self._on = np.where(self.mask, num_levels - 1, 0).astype(np.uint8)
        self._off = np.zeros_like(self._on)

    @classmethod
    def for_simulator(cls, sim) -> "NoDataPattern":
        """The pattern of a :class:`~raspv_spv.simulator.PhospheneSimulator`'s map."""
        return cls(sim.map.display_centres, sim.map.dropped, sim.config.device.field == "circular", sim.num_levels)

    def levels(self, now_s: float) -> np.ndarray:
        """(N,) uint8 levels at time ``now_s`` [s] (do not modify: shared between calls)."""
        return self._on if (now_s * BLINK_HZ) % 1.0 < 0.5 else self._off
