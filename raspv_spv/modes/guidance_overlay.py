"""Guidance overlay: a direction marker at the edge of the phosphene field (no ROS).

When the navigation path is not in view — the path overlay would light no phosphene, because
the path turns away behind the subject or leaves the prosthesis' narrow field — the subject
needs to know which way to turn. This overlay lights the phosphenes at the edge of the field in
the direction of the navigation assistant's next waypoint (``extras["nav_guidance"]``, a
:class:`~raspv_nav.guidance.Guidance` in the world frame W) or, when the path itself is at
hand (``nav_path``), of the point ``marker_lookahead`` m along it: that point on the floor
(z = ``path_height``) is brought into the camera frame C with the camera pose and projected
with the prosthesis' K_P; its direction from the field centre picks a sector of
±``marker_width_deg``/2 (polar angle in the phosphene image), and the phosphenes of that sector
within ``marker_depth`` (fraction of the sector's outermost radius) of its edge are the marker.
A waypoint behind the camera points the marker to the side it lies on.

Nothing is lit while the path is in view (when ``nav_path`` and depth are present, with the
path overlay's own visibility test), when the waypoint itself projects inside the field, or
before the first guidance.
"""
from __future__ import annotations

import math

import numpy as np

from raspv_nav.local_planner import lookahead_point
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.base import Overlay
from raspv_spv.modes.path_overlay import PathOverlay
from raspv_spv.sampling import Sampling


class GuidanceOverlay(Overlay):
    name = "guidance"
    description = "a direction marker at the field's edge towards the next waypoint when the path is out of view"
    needs = frozenset({"camera", "camera_pose"})
    optional_inputs = frozenset({"nav_guidance", "nav_path", "depth"})
    defaults = {
        "marker_width_deg": 30.0,     # angular width of the marker sector, polar angle in the image [deg]
        "marker_depth": 0.25,         # marker thickness as a fraction of the field radius in its direction
        "path_height": 0.0,           # world z of the floor [m]
        "marker_lookahead": 3.0,      # with the path at hand, point at the path this far ahead [m]
    }

    def __init__(self, settings=None) -> None:
        super().__init__(settings)
        self._path = PathOverlay(self.settings)

    def direction(self, inputs: FrameInputs, sampling: Sampling) -> float | None:
        """Polar angle [rad] in the phosphene image (x right, y down) towards the waypoint, or
        None when no marker is due (no guidance, path visible, waypoint inside the field)."""
        g = inputs.extras.get("nav_guidance")
        waypoint = getattr(g, "next_waypoint", None)
        if waypoint is None:
            return None
        pose = np.asarray(inputs.camera_pose, dtype=float)
        path = inputs.extras.get("nav_path")
        if path is not None and len(path) >= 2:
            if inputs.depth is not None and self._path.highlight(inputs, sampling).any():
                return None                               # the path overlay shows the way
            # a point farther along the path than the DWA's waypoint: one right at the feet is
            # always below the field and would only say "down"
            waypoint = lookahead_point(np.asarray(path, dtype=float)[:, :2], pose[:2, 3],
                                       self.settings["marker_lookahead"])
        p = np.array([waypoint[0], waypoint[1], self.settings["path_height"]], dtype=float)
        pc = (p - pose[:3, 3]) @ pose[:3, :3]             # world → camera: Rᵀ (p − t)
        K = sampling.K_P
        centre = np.array([K[0, 2], K[1, 2]])
        if pc[2] > 1e-3:
            uv = np.array([K[0, 0] * pc[0] / pc[2], K[1, 1] * pc[1] / pc[2]]) + centre
            if _inside_field(uv, sampling):
                return None
            return math.atan2(uv[1] - centre[1], uv[0] - centre[0])
        return 0.0 if pc[0] >= 0 else math.pi             # behind: point to its side

    def highlight(self, inputs: FrameInputs, sampling: Sampling) -> np.ndarray:
        angle = self.direction(inputs, sampling)
        if angle is None:
            return np.zeros(sampling.count, bool)
        K = sampling.K_P
        rel = sampling.centres - np.array([K[0, 2], K[1, 2]])
        radius = np.hypot(rel[:, 0], rel[:, 1])
        off = np.abs(np.mod(np.arctan2(rel[:, 1], rel[:, 0]) - angle + math.pi, 2 * math.pi) - math.pi)
        sector = off <= math.radians(self.settings["marker_width_deg"]) / 2
        if not sector.any():
            return sector
        edge = radius[sector].max()
        return sector & (radius >= edge * (1.0 - self.settings["marker_depth"]))


def _inside_field(uv: np.ndarray, sampling: Sampling) -> bool:
    """True when image point ``uv`` lies among the phosphenes (within one spacing of the
    nearest centre, inside their extent)."""
    d = np.hypot(*(sampling.centres - uv).T)
    spacing = np.sort(np.hypot(*(sampling.centres[1:] - sampling.centres[0]).T))[0] if sampling.count > 1 else 1.0
    return bool(d.min() <= 1.5 * spacing)
