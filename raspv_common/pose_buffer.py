"""Stamped poses, interpolated in time: the small part of tf2 this project needs (no rclpy).

A :class:`PoseBuffer` keeps the recent history of one transform (parent ← child, 4×4, e.g.
world ← camera from ``/camera/pose`` or base ← head from ``/head/orientation``) and answers
"where was it at time t?" with linear interpolation of the translation and spherical linear
interpolation (slerp) of the rotation between the two samples around t. Nodes use it to
combine data of different stamps: a depth frame with the camera pose *at its stamp*, a scene of
frame t with the head pose of frame t, a reprojection from the capture pose to the newest one.

Times are float seconds on whatever clock stamped the messages (ROS time, sim time, bag time):
the buffer never reads a clock itself, so replayed bags work unchanged. A stamp that goes back
by more than ``reset_on_jump_s`` (a bag looping, the simulator reset) clears the history.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from raspv_common.rotations import matrix_to_quaternion, quaternion_to_matrix, slerp_quaternion


class PoseLookupError(LookupError):
    """No pose can be given for the asked time (empty buffer, or too far outside its span)."""


@dataclass(frozen=True)
class StampedPose:
    stamp: float          # s
    matrix: np.ndarray    # 4×4 parent ← child


def interpolate_pose(T0: np.ndarray, T1: np.ndarray, s: float) -> np.ndarray:
    """The rigid transform a fraction ``s`` of the way from ``T0`` to ``T1`` (4×4 each)."""
    q = slerp_quaternion(np.array(matrix_to_quaternion(T0[:3, :3])), np.array(matrix_to_quaternion(T1[:3, :3])), s)
    T = np.eye(4)
    T[:3, :3] = quaternion_to_matrix(*q)
    T[:3, 3] = (1.0 - s) * T0[:3, 3] + s * T1[:3, 3]
    return T


class PoseBuffer:
    """History of one stamped transform, looked up at any time inside it (interpolated).

    ``max_age_s`` bounds the history behind the newest sample; ``max_extrapolation_s`` is how
    far outside the stored span a lookup may be answered with the nearest sample (the pose is
    held, not extrapolated): a frame stamped a few ms after the last pose still gets one.
    """

    def __init__(self, max_age_s: float = 10.0, max_extrapolation_s: float = 0.1,
                 reset_on_jump_s: float = 1.0) -> None:
        if max_age_s <= 0 or max_extrapolation_s < 0 or reset_on_jump_s <= 0:
            raise ValueError("max_age_s and reset_on_jump_s must be > 0, max_extrapolation_s >= 0")
        self.max_age_s = max_age_s
        self.max_extrapolation_s = max_extrapolation_s
        self.reset_on_jump_s = reset_on_jump_s
        self._stamps: list[float] = []
        self._poses: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self._stamps)

    def clear(self) -> None:
        self._stamps.clear()
        self._poses.clear()

    def add(self, stamp: float, matrix: np.ndarray) -> None:
        """Insert a pose (out-of-order inserts are placed in order; the same stamp replaces)."""
        T = np.asarray(matrix, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"a pose must be a finite 4x4 matrix, got shape {T.shape}")
        if not math.isfinite(stamp):
            raise ValueError(f"pose stamp must be finite, got {stamp}")
        if self._stamps and stamp < self._stamps[-1] - self.reset_on_jump_s:
            self.clear()                                  # time went back: a loop or a reset
        i = bisect.bisect_left(self._stamps, stamp)
        if i < len(self._stamps) and self._stamps[i] == stamp:
            self._poses[i] = T
        else:
            self._stamps.insert(i, stamp)
            self._poses.insert(i, T)
        cutoff = self._stamps[-1] - self.max_age_s
        k = bisect.bisect_left(self._stamps, cutoff)
        if k > 0 and len(self._stamps) > 2:
            k = min(k, len(self._stamps) - 2)             # always keep two samples to interpolate
            del self._stamps[:k]
            del self._poses[:k]

    def latest(self) -> StampedPose | None:
        if not self._stamps:
            return None
        return StampedPose(self._stamps[-1], self._poses[-1].copy())

    def span(self) -> tuple[float, float] | None:
        """(oldest, newest) stamp held, or None when empty."""
        return (self._stamps[0], self._stamps[-1]) if self._stamps else None

    def lookup(self, stamp: float) -> np.ndarray:
        """The pose at ``stamp`` (4×4 copy); raises :class:`PoseLookupError` when none can be given."""
        n = len(self._stamps)
        if n == 0:
            raise PoseLookupError("no pose received yet")
        first, last = self._stamps[0], self._stamps[-1]
        if stamp <= first:
            if first - stamp > self.max_extrapolation_s:
                raise PoseLookupError(f"pose at t={stamp:.3f} s is {first - stamp:.3f} s older than the oldest held")
            return self._poses[0].copy()
        if stamp >= last:
            if stamp - last > self.max_extrapolation_s:
                raise PoseLookupError(f"pose at t={stamp:.3f} s is {stamp - last:.3f} s newer than the newest held")
            return self._poses[-1].copy()
        i = bisect.bisect_right(self._stamps, stamp)
        t0, t1 = self._stamps[i - 1], self._stamps[i]
        return interpolate_pose(self._poses[i - 1], self._poses[i], (stamp - t0) / (t1 - t0))

    def predict(self, stamp: float, max_ahead_s: float) -> np.ndarray | None:
        """The pose at ``stamp``: looked up inside the span; after the newest sample, continued
        at the velocity between the two newest samples (constant linear and angular velocity,
        at most ``max_ahead_s`` ahead; beyond that the pose there is held); None when empty.
        For data that comes before its pose (images ahead of a lagging odometry)."""
        if not self._stamps:
            return None
        last = self._stamps[-1]
        if stamp <= last:
            return self.lookup_or_none(stamp)
        if len(self._stamps) < 2:
            return self._poses[-1].copy()
        t0 = self._stamps[-2]
        ahead = min(stamp, last + max_ahead_s)
        return interpolate_pose(self._poses[-2], self._poses[-1], (ahead - t0) / (last - t0))

    def lookup_or_none(self, stamp: float) -> np.ndarray | None:
        try:
            return self.lookup(stamp)
        except PoseLookupError:
            return None
