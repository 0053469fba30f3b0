"""Depth: closer is brighter (paper §III-C1)."""
from __future__ import annotations

import numpy as np

from raspv_spv.modes.base import Mode, quantise


class DepthMode(Mode):
    """level = ⌈(max_depth − d)/max_depth·(N_L−1)⌉ for the depth d [m] at P_i^C; depth beyond
    ``max_depth``, missing (NaN, 0, inf) or outside the camera gives 0."""

    name = "depth"
    description = "depth: closer is brighter, off beyond max_depth"
    needs = frozenset({"depth", "camera"})
    defaults = {"max_depth": 3.0}

    def levels(self, inputs, sampling, num_levels):
        max_depth = float(self.settings["max_depth"])
        d = sampling.sample(inputs.depth, fill=np.nan).astype(np.float64)
        valid = np.isfinite(d) & (d > 0) & (d < max_depth)
        frac = np.where(valid, (max_depth - np.where(valid, d, max_depth)) / max_depth, 0.0)
        return quantise(frac, num_levels)
