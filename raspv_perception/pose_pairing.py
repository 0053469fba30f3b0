"""Depth frames paired with the camera pose of their stamp (no rclpy).

A node that uses ``/camera/pose`` as a prior for a depth frame takes the pose nearest the
frame's stamp (within ``max_age_s``). Processing each frame on arrival makes that pose depend
on timing: the simulator publishes a frame's pose right after its images, so the frame finds
its own pose, the previous frame's, or none (the first frame of a graph) — and a lockstep run
no longer repeats. With ``wait`` each frame waits for the pose of its own stamp (lockstep: the
simulator publishes one with every frame, and sends the next frame only after this one was
answered), so what the frame is processed with is fixed by the frame, never by timing.
"""
from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

STAMP_TOLERANCE_S = 1e-3     # a pose this close to the frame's stamp is the frame's own [s]


class PosePairing:
    """Stamped poses (4×4, world from camera) and depth frames waiting for theirs."""

    def __init__(self, max_age_s: float, wait: bool = False, history: int = 50) -> None:
        self.max_age_s = float(max_age_s)
        self.wait = bool(wait)
        self.poses: deque[tuple[float, np.ndarray]] = deque(maxlen=history)
        self.waiting: tuple[float, Any] | None = None    # (stamp [s], frame) awaiting its pose
        self.dropped = 0                                 # frames replaced while waiting

    def prior(self, stamp: float) -> np.ndarray | None:
        """The pose nearest ``stamp`` [s], if within ``max_age_s``."""
        if not self.poses:
            return None
        t, T = min(self.poses, key=lambda tp: abs(tp[0] - stamp))
        return T if abs(t - stamp) <= self.max_age_s else None

    def _has_pose_at_or_after(self, stamp: float) -> bool:
        return any(t >= stamp - STAMP_TOLERANCE_S for t, _ in self.poses)

    def add_frame(self, stamp: float, frame: Any) -> tuple[float, Any] | None:
        """A depth frame arrived: (stamp, frame) to process now, or None while it waits for its
        pose (``wait``; a newer frame replaces a waiting one, counted in ``dropped``)."""
        if not self.wait or self._has_pose_at_or_after(stamp):
            return stamp, frame
        if self.waiting is not None:
            self.dropped += 1
        self.waiting = (stamp, frame)
        return None

    def add_pose(self, stamp: float, world_from_camera: np.ndarray) -> tuple[float, Any] | None:
        """A pose arrived: the waiting frame it releases (its stamp is at or before the pose's), if any."""
        self.poses.append((float(stamp), world_from_camera))
        if self.waiting is not None and self.waiting[0] <= stamp + STAMP_TOLERANCE_S:
            released, self.waiting = self.waiting, None
            return released
        return None
