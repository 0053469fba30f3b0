"""Views seen before, to fill a head turn beyond the newest camera frame (no ROS).

Display-time reprojection (:mod:`raspv_spv.reprojection`) turns the newest camera frame to the
head's newest orientation; what the turned view sees outside that frame (beyond the simulator's
render margin) is dark until a camera frame taken in the new direction has come through the
camera, scene and spv nodes — 100–300 ms for a 40° head step. A wearer who looks back and forth
turns towards views the display has already shown. :class:`ViewMemory` keeps recent frames by
*where the camera looked* (one per direction at least ``min_apart_deg`` apart, the newest of
each), and the display samples the phosphenes outside the newest frame from the newest
remembered frame that saw them, with that frame's own mode and its capture orientation — the
new view at once from what was already rendered, refined by the camera frame that follows.

A remembered frame is used only while it is valid for rotations alone: younger than
``max_age_s`` and taken with the base within ``max_moved_m`` of where it stands now (only the
rotation is re-projected: walking would move near things), and only when the base's pose is
known (``/odom``: the simulator); without odometry nothing is remembered. Moving objects (people
walking) are shown where they were until the camera frame comes.

Frames: R_{W←C} is the camera's orientation in the world (``/camera/pose`` W ← C, or the base's
``/odom`` W ← B times the head); positions in the world frame [m]; times [s] on the messages' clock.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

MIN_APART_DEG = 10.0        # a frame replaces remembered frames looking within this angle [deg]
MAX_AGE_S = 10.0            # remembered frames older than this are forgotten [s]
MAX_MOVED_M = 0.05          # ... and unused once the base has moved this far from where they were taken [m]
MAX_VIEWS = 8               # directions remembered
MAX_FILL_VIEWS = 3          # remembered frames sampled per display tick at most


def _angle_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    c = (float(np.trace(Ra.T @ Rb)) - 1.0) / 2.0
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


@dataclass(frozen=True)
class RememberedView:
    """A frame (:class:`~raspv_spv.reprojection.DisplayFrame`) with the camera's orientation
    R_{W←C} (3×3) and the base's position (3,) [m, world] at its capture stamp."""

    frame: object
    world_from_camera: np.ndarray
    position: np.ndarray

    @property
    def stamp(self) -> float:
        return self.frame.stamp


class ViewMemory:
    """Recent frames, one per viewing direction (thread-safe: frames are added by the node's
    compute thread, asked by the display thread)."""

    def __init__(self, max_age_s: float = MAX_AGE_S, min_apart_deg: float = MIN_APART_DEG,
                 max_moved_m: float = MAX_MOVED_M, max_views: int = MAX_VIEWS) -> None:
        if max_age_s < 0 or min_apart_deg <= 0 or max_moved_m < 0 or max_views < 1:
            raise ValueError("max_age_s, max_moved_m >= 0, min_apart_deg > 0, max_views >= 1")
        self.max_age_s, self.min_apart_deg = max_age_s, min_apart_deg
        self.max_moved_m, self.max_views = max_moved_m, max_views
        self._views: list[RememberedView] = []          # oldest first
        self._lock = threading.Lock()

    @property
    def enabled(self) -> bool:
        return self.max_age_s > 0

    def __len__(self) -> int:
        with self._lock:
            return len(self._views)

    def clear(self) -> None:
        with self._lock:
            self._views.clear()

    def remember(self, frame, world_from_camera: np.ndarray, position: np.ndarray) -> None:
        """Keep ``frame`` (captured at ``frame.stamp`` looking along R_{W←C} ``world_from_camera``,
        the base at ``position``): it replaces the frames that looked within ``min_apart_deg``
        of it; frames older than ``max_age_s`` (or stamped after it: time went back, a bag
        looping) are forgotten, and the oldest beyond ``max_views``."""
        if not self.enabled:
            return
        view = RememberedView(frame, np.asarray(world_from_camera, float)[:3, :3], np.asarray(position, float)[:3])
        with self._lock:
            self._views = [v for v in self._views
                           if frame.stamp - self.max_age_s < v.stamp < frame.stamp
                           and _angle_deg(v.world_from_camera, view.world_from_camera) >= self.min_apart_deg]
            self._views.append(view)
            del self._views[:-self.max_views]

    def candidates(self, stamp: float, position: np.ndarray, exclude=None) -> list[RememberedView]:
        """Remembered views usable at ``stamp`` with the base at ``position``, newest first,
        without the frame ``exclude`` (the one the display already shows)."""
        position = np.asarray(position, float)[:3]
        with self._lock:
            views = list(self._views)
        return [v for v in reversed(views)
                if v.frame is not exclude and stamp - v.stamp <= self.max_age_s
                and float(np.linalg.norm(v.position - position)) <= self.max_moved_m]


def fill_outside(levels: np.ndarray, inside: np.ndarray, sources) -> tuple[np.ndarray, int]:
    """``levels`` (N,) with the phosphenes outside the shown frame (``inside`` False) taken
    from ``sources``: (levels (N,), inside (N,)) of remembered frames, newest first; each
    phosphene from the first that saw it. Returns (levels, phosphenes filled)."""
    missing = ~np.asarray(inside, bool)
    if not missing.any():
        return levels, 0
    out = np.array(levels, copy=True)
    filled = 0
    for other, seen in sources:
        take = missing & np.asarray(seen, bool)
        if take.any():
            out[take] = np.asarray(other)[take]
            missing &= ~take
            filled += int(take.sum())
        if not missing.any():
            break
    return out, filled



@dataclass(frozen=True)
class SceneResult:
    """Scene perception's own result for the depth frame captured at ``stamp`` [s]: its
    ``labels`` (registered to that depth image) and the camera pose W ← C (4×4) at the stamp."""

    stamp: float
    labels: np.ndarray
    world_from_camera: np.ndarray


def remembered_scene_labels(views, world_from_new: np.ndarray, before: float, exclude: float | None = None,
                            limit: int = MAX_FILL_VIEWS) -> list[tuple[np.ndarray, np.ndarray]]:
    """Scene results remembered by direction (``views``: :class:`RememberedView` of
    :class:`SceneResult`, newest first) for a depth frame the camera took at W ← C'
    ``world_from_new`` (4×4): (labels, C' ← C 4×4) of at most ``limit`` results of frames taken
    before ``before`` [s], without the one of stamp ``exclude``.
    :func:`raspv_perception.scene_carry.carry_labels` takes them as ``earlier``: a head turned back
    to a direction seen before gets that direction's labels at once. Only scene perception's own
    results are remembered, never labels carried into a frame (carrying a carried frame again
    would continue its guesses)."""
    new_from_world = np.linalg.inv(np.asarray(world_from_new, dtype=np.float64))
    out = []
    for view in views:
        result = view.frame
        if result.stamp >= before or (exclude is not None and abs(result.stamp - exclude) < 1e-6):
            continue
        out.append((result.labels, new_from_world @ np.asarray(result.world_from_camera, dtype=np.float64)))
    return out[:limit]
