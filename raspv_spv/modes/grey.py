"""Downsampling: each phosphene shows the grey value its ray sees (paper §III-C1)."""
from __future__ import annotations

import numpy as np

from raspv_spv.modes.base import Mode, quantise

# ITU-R BT.601 luma, as OpenCV's RGB → grey.
_LUMA = np.array([0.299, 0.587, 0.114])


class GreyMode(Mode):
    """level = ⌈g/255·(N_L−1)⌉ with g the luma of the colour pixel at P_i^C."""

    name = "grey"
    description = "downsampling: brightness of the grey image at each phosphene"
    needs = frozenset({"color", "camera"})

    def levels(self, inputs, sampling, num_levels):
        rgb = sampling.sample(inputs.color).astype(np.float64)
        return quantise(rgb @ _LUMA / 255.0, num_levels)
