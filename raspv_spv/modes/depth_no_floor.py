"""Depth with the floor removed: the depth mode (closer is brighter) with every phosphene that
sees floor — free or next to an obstacle — off, so only what stands on the floor shows."""
from __future__ import annotations

from raspv_perception import scene_labels as L
from raspv_spv.modes.depth import DepthMode


class DepthNoFloorMode(DepthMode):
    name = "depth_no_floor"
    description = "depth (closer is brighter) with the floor off"
    needs = frozenset({"depth", "scene_labels", "camera"})

    def levels(self, inputs, sampling, num_levels):
        out = super().levels(inputs, sampling, num_levels)
        labels = sampling.sample(inputs.scene_labels, fill=L.NONE)
        out[(labels == L.FLOOR) | (labels == L.FLOOR_BLOCKED)] = 0
        return out
