"""The map: keyframes, their poses, the pose graph's edges, the place database and the anchor of
the map frame (no ROS).

Frames: S is the SLAM frame (the first keyframe's camera frame of the run that built the map);
keyframe poses are S ← K.

Sub-maps (ORB-SLAM's atlas, at this project's scale): every keyframe belongs to one sub-map
(``segment``, 0 = the first map). A sub-map started after tracking was lost in an unmapped place
is a disconnected part of the pose graph whose poses are in a frame S_j of its own (placed where
the last tracked pose was, since the motion while lost is unknown); nothing relates S_j to S
until a place of another sub-map is recognised and verified, when :meth:`merge_segments`
re-expresses it in the older sub-map's frame with one rigid transform. M is the map frame users see: M ← S is the identity-like "level
camera" turn until the map is anchored to a floor, then gravity-aligned (z up, z = 0 on the
floor). Thread-safe: tracking reads while the loop closer adds edges and corrects poses.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Callable

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.rgbd_odometry import LEVEL_WORLD_FROM_CAMERA, nearest_rigid
from raspv_slam.config import SlamConfig
from raspv_slam.keyframe import Keyframe
from raspv_slam.place_recognition import PlaceDatabase
from raspv_slam.pose_graph import EDGE_KINDS
from raspv_slam.se3 import inverse, pose_distance

FRAME_CACHE = 12            # decoded keyframes kept for registration


@dataclass(frozen=True)
class Edge:
    """A measured relative pose ``a ← b`` between keyframes a and b."""

    a: int
    b: int
    a_from_b: np.ndarray
    kind: str                # odometry (tracking chain), covisibility (nearby), loop (place recognition)


class SlamMap:
    def __init__(self, intrinsics: CameraIntrinsics, config: SlamConfig) -> None:
        self.intrinsics = intrinsics
        self.config = config
        self.keyframes: dict[int, Keyframe] = {}
        self._poses: dict[int, np.ndarray] = {}
        self.edges: list[Edge] = []
        self.parent: dict[int, int] = {}            # odometry parent of each keyframe
        self.transient: list[int] = []              # localisation mode's keyframes (not part of the map)
        self.world_from_slam = LEVEL_WORLD_FROM_CAMERA.copy()
        self.anchored = False
        self.places = PlaceDatabase(config)
        self.lock = threading.RLock()
        self.generation = 0                         # counts pose corrections
        self.loop_generation = 0                    # counts corrections that closed a loop
        self.merge_generation = 0                   # counts sub-map merges
        self.segment: dict[int, int] = {}           # keyframe → its sub-map (0: the first map)
        self._next_segment = 1
        self._next_id = 0
        self._frames: OrderedDict[int, object] = OrderedDict()

    # -- keyframes and poses ------------------------------------------------------------------
    def __len__(self) -> int:
        """Keyframes of the map (without localisation's transient ones)."""
        return len(self.keyframes) - len(self.transient)

    def new_id(self) -> int:
        with self.lock:
            self._next_id += 1
            return self._next_id - 1

    def add_keyframe(self, kf: Keyframe, slam_from_kf: np.ndarray, parent: int | None = None,
                     parent_from_kf: np.ndarray | None = None, transient: bool = False,
                     parent_pose_seen: np.ndarray | None = None, segment: int | None = None) -> None:
        """``parent_pose_seen``: the parent's S ← K the caller composed ``slam_from_kf`` with; a
        loop correction applied since then moves the new keyframe with its parent (it must not
        be left at the stale pose). ``segment``: its sub-map (default: the parent's, else 0);
        a merge since the caller read the parent's pose moves it with the parent too."""
        with self.lock:
            self.keyframes[kf.id] = kf
            if segment is None:
                segment = self.segment.get(parent, 0) if parent is not None else 0
            self.segment[kf.id] = segment
            if parent_pose_seen is not None and parent in self._poses:
                slam_from_kf = self._poses[parent] @ inverse(parent_pose_seen) @ np.asarray(slam_from_kf, np.float64)
            # stored rigid: a pose composed with the inverse (transpose) of a slightly skewed one
            # grows the skew, and each keyframe placed on its parent this way cubed it (a walk's
            # keyframe poses went from round-off to 1e11 in 35 keyframes without a correction)
            self._poses[kf.id] = nearest_rigid(np.asarray(slam_from_kf, dtype=np.float64))
            self._next_id = max(self._next_id, kf.id + 1)
            if transient:
                self.transient.append(kf.id)
                return
            if parent is not None:
                self.parent[kf.id] = parent
                self.edges.append(Edge(parent, kf.id, np.array(parent_from_kf, dtype=np.float64), "odometry"))

    def replace_features(self, kf_id: int, features) -> None:
        """Replace a keyframe's features by the same ones moved (e.g. turned to mid-row time: same
        descriptors); its images, pose, edges and place entry stay."""
        from dataclasses import replace

        with self.lock:
            kf = self.keyframes[kf_id]
            if len(features) != len(kf.features):
                raise ValueError(f"keyframe {kf_id} has {len(kf.features)} features, got {len(features)}")
            self.keyframes[kf_id] = replace(kf, features=features)
            self._frames.pop(kf_id, None)

    def prune_transient(self, keep_last: int, keep: set = frozenset()) -> None:
        """Drop the oldest transient keyframes beyond ``keep_last`` (but those in ``keep``)."""
        with self.lock:
            while len(self.transient) > keep_last:
                old = next((k for k in self.transient if k not in keep), None)
                if old is None:
                    return
                self.transient.remove(old)
                del self.keyframes[old], self._poses[old]
                self.segment.pop(old, None)
                self._frames.pop(old, None)

    @property
    def permanent(self) -> list[int]:
        """Keyframes that belong to the map (not localisation's transient ones)."""
        with self.lock:
            transient = set(self.transient)
            return [k for k in self.keyframes if k not in transient]

    def pose(self, kf_id: int) -> np.ndarray:
        """S ← K of a keyframe (a copy)."""
        with self.lock:
            return self._poses[kf_id].copy()

    def relative(self, a: int, b: int) -> np.ndarray:
        """A ← B of two keyframes, both poses read at once (not across a loop correction)."""
        with self.lock:
            return inverse(self._poses[a]) @ self._poses[b]

    def poses(self) -> dict[int, np.ndarray]:
        with self.lock:
            return {k: v.copy() for k, v in self._poses.items()}

    def add_edge(self, edge: Edge) -> None:
        if edge.kind not in EDGE_KINDS:
            raise ValueError(f"unknown edge kind {edge.kind!r}")
        with self.lock:
            self.edges.append(edge)

    def remove_edges(self, edges: list[Edge]) -> None:
        if not edges:
            return
        drop = {id(e) for e in edges}
        with self.lock:
            self.edges = [e for e in self.edges if id(e) not in drop]

    def connected(self, a: int, b: int) -> bool:
        with self.lock:
            return any({e.a, e.b} == {a, b} for e in self.edges)

    def apply_correction(self, optimised: dict[int, np.ndarray], closed_loop: bool) -> None:
        """Replace the poses of the optimised keyframes; keyframes added since the optimisation
        started move with their odometry parent."""
        with self.lock:
            before = self._poses
            after = {k: np.array(v, dtype=np.float64) for k, v in optimised.items() if k in before}
            for k in sorted(set(before) - set(after)):
                p = self.parent.get(k)
                if p is not None and p in after:
                    after[k] = nearest_rigid(after[p] @ inverse(before[p]) @ before[k])
                else:
                    after[k] = before[k]
            self._poses = after
            self.generation += 1
            if closed_loop:
                self.loop_generation += 1

    def nearby(self, slam_from_camera: np.ndarray, radius: float, angle_deg: float,
               exclude: set[int] = frozenset(), segment: int | None = None) -> list[int]:
        """Keyframes within ``radius`` metres and ``angle_deg`` of a pose, nearest first
        (distance plus angle weighted 1 m per 60°); with ``segment``, only that sub-map's (the
        pose is in its frame; other sub-maps' poses are in frames of their own)."""
        with self.lock:
            items = list(self._poses.items())
            segments = dict(self.segment)
        out = []
        for k, p in items:
            if k in exclude or (segment is not None and segments.get(k) != segment):
                continue
            dt, dr = pose_distance(p, slam_from_camera)
            if dt <= radius and dr <= angle_deg:
                out.append((dt + dr / 60.0, k))
        return [k for _, k in sorted(out)]

    def view_overlap(self, kf_id: int, kf_from_camera: np.ndarray) -> float:
        """Share of a keyframe's 3-D feature points that a camera at ``kf_from_camera`` sees (in
        front of it, inside the image)."""
        f = self.keyframes[kf_id].features
        p = f.points[f.with_depth].astype(np.float64)
        if not len(p):
            return 0.0
        camera_from_kf = inverse(kf_from_camera)
        q = p @ camera_from_kf[:3, :3].T + camera_from_kf[:3, 3]
        u, v, z = self.intrinsics.project(q)
        return float(((z > self.config.min_depth) & self.intrinsics.contains(u, v)).mean())

    def covisible(self, slam_from_camera: np.ndarray, min_overlap: float, exclude: set[int] = frozenset(),
                  radius: float = 2.0, angle_deg: float = 90.0, segment: int | None = None) -> list[int]:
        """Keyframes (of ``segment``, within ``radius`` and ``angle_deg`` of the pose) sharing at
        least ``min_overlap`` of their points with a camera at that pose, most shared first."""
        scored = []
        for k in self.nearby(slam_from_camera, radius, angle_deg, exclude, segment):
            overlap = self.view_overlap(k, inverse(self.pose(k)) @ slam_from_camera)
            if overlap >= min_overlap:
                scored.append((-overlap, k))
        return [k for _, k in sorted(scored)]

    # -- sub-maps -------------------------------------------------------------------------------
    def new_segment(self) -> int:
        """A fresh sub-map id (its first keyframe is added with ``segment=`` that id)."""
        with self.lock:
            self._next_segment = max(self._next_segment, max(self.segment.values(), default=0) + 1)
            self._next_segment += 1
            return self._next_segment - 1

    def segment_of(self, kf_id: int) -> int:
        with self.lock:
            return self.segment.get(kf_id, 0)

    def segments(self) -> dict[int, list[int]]:
        """Sub-map → its keyframes (localisation's transient ones included)."""
        with self.lock:
            out: dict[int, list[int]] = {}
            for k, s in self.segment.items():
                out.setdefault(s, []).append(k)
            return out

    def merge_segments(self, keep: int, drop: int, keep_from_drop: np.ndarray) -> int:
        """Re-express every keyframe of sub-map ``drop`` in the frame of ``keep`` (S_keep ←
        S_drop, one rigid transform) and make them part of it. Returns the keyframes moved."""
        T = nearest_rigid(np.asarray(keep_from_drop, dtype=np.float64))
        with self.lock:
            moved = [k for k, s in self.segment.items() if s == drop]
            for k in moved:
                self._poses[k] = nearest_rigid(T @ self._poses[k])
                self.segment[k] = keep
            self.generation += 1
            self.merge_generation += 1
            return len(moved)

    # -- decoded keyframes --------------------------------------------------------------------
    def frame(self, kf_id: int, make: Callable[[Keyframe], object]):
        """A keyframe decoded for registration (``make``: FramePreparer.keyframe_frame), kept in a
        small LRU cache."""
        with self.lock:
            frame = self._frames.get(kf_id)
            if frame is not None:
                self._frames.move_to_end(kf_id)
                return frame
            kf = self.keyframes[kf_id]
        frame = make(kf)
        with self.lock:
            self._frames[kf_id] = frame
            while len(self._frames) > FRAME_CACHE:
                self._frames.popitem(last=False)
        return frame

    # -- frames -------------------------------------------------------------------------------
    def world_from_camera(self, slam_from_camera: np.ndarray) -> np.ndarray:
        with self.lock:
            return self.world_from_slam @ slam_from_camera

    def anchor(self, world_from_slam: np.ndarray) -> None:
        with self.lock:
            self.world_from_slam = np.array(world_from_slam, dtype=np.float64)
            self.anchored = True

    @property
    def nbytes(self) -> int:
        with self.lock:
            return sum(kf.nbytes for kf in self.keyframes.values()) + self.places.nbytes
