"""Staircase overlay (paper §IV-B, Fig. 10): the 3-D wireframe of a detected staircase — every
tread's outline and the risers' edges — projected onto the phosphenes at full level, the rest
dimmed (:meth:`Overlay.apply`), over any representation mode.

Input (optional): ``extras["stairs"]``, a list of :class:`~raspv_perception.stair_model.Staircase`
in the camera frame C of the depth frame they were detected in (the spv node fills it from
``/stairs``; an empty list when none is detected). Without it nothing is highlighted.
Wireframe points hidden behind the depth image (e.g. the far edges of a descending stair's
treads) are not drawn.
"""
from __future__ import annotations

import numpy as np

from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.base import Overlay
from raspv_spv.modes.projected_lines import densify_segments, phosphenes_on_lines, visible_in_depth
from raspv_spv.sampling import Sampling


class StairsOverlay(Overlay):
    name = "stairs"
    description = "highlight a detected staircase's steps (3-D wireframe), dimming the rest"
    needs = frozenset({"camera"})
    optional_inputs = frozenset({"stairs"})          # no detection yet: nothing to draw
    defaults = {
        "stairs_width_deg": 2.0,          # drawn line width [deg of visual field]
        "stairs_occlusion_tolerance": 0.1,  # a wireframe point counts as visible up to this behind the depth [m]
    }

    def visible_points(self, inputs: FrameInputs) -> np.ndarray:
        """Wireframe points (M, 3) in C, NaN where hidden or between segments."""
        segments = [s.segments() for s in inputs.extras.get("stairs") or []]
        if not segments:
            return np.empty((0, 3))
        pc = densify_segments(np.concatenate(segments), 0.03)       # NaN rows separate the segments
        pc[~visible_in_depth(pc, inputs, self.settings["stairs_occlusion_tolerance"])] = np.nan
        return pc

    def highlight(self, inputs: FrameInputs, sampling: Sampling) -> np.ndarray:
        key = (self.name, self.settings["stairs_occlusion_tolerance"])
        points = inputs.cached(key, lambda: self.visible_points(inputs))       # once per frame
        return phosphenes_on_lines(points, sampling, self.settings["stairs_width_deg"])
