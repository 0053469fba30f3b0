"""The SLAM system: one object that takes RGB-D frames and returns poses (no ROS).

Per frame (:meth:`SlamSystem.process`): the frame is registered to its reference keyframe
(ORB + PnP, refined by dense RGB-D registration, :mod:`frame_registration`); when that fails
the constant-velocity motion model carries the pose, and after ``lost_after`` failures the
state is LOST and every frame tries to relocalise in the map (place recognition + PnP). Lost for
``new_map_after`` seconds in a place the map does not know, a new sub-map starts (NEW_MAP, its
own frame, ``map_id``); the loop closer keeps looking for the older maps' places and merges the
sub-maps when it finds one (MAP_MERGED, ORB-SLAM's atlas at this project's scale). When
the view leaves the reference keyframe, a nearby keyframe is reused or a new one is made; the
loop closer (:mod:`loop_closing`, a background thread) links it to covisible keyframes and to
places seen before and optimises the pose graph; tracking picks the corrected poses up at its
next frame.

Frames (REP 105): M map, O odometry (continuous), C camera optical; S the first keyframe's
camera frame (internal). ``map_from_camera = map_from_odom @ odom_from_camera``; odometry
integrates the frame-to-frame motions only, so it never jumps; loop closures and
relocalisations move ``map_from_odom``.
"""
from __future__ import annotations

import math
import time
from collections import OrderedDict, deque
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.rgbd_odometry import world_from_floor_plane
from raspv_slam.config import SlamConfig
from raspv_slam.frame import Frame, FramePreparer
from raspv_slam.frame_registration import FrameRegistrar
from raspv_slam.keyframe import Keyframe, encode_images
from raspv_slam.loop_closing import LoopCloser
from raspv_slam.results import MapSnapshot, SlamResult, TrackingState
from raspv_slam.rolling_shutter import rotation_rate, skew_px
from raspv_slam.se3 import inverse, motion_size
from raspv_slam.slam_map import SlamMap

HISTORY = 300               # frames whose poses anchor_to_floor can still look up
TRANSIENT_KEYFRAMES = 30    # keyframes kept in localisation mode outside the map's views
STAMP_TOLERANCE_S = 1e-3
# the rolling-shutter correction predicts this frame's rotation rate from the last interval: over
# longer intervals a hand-held camera's rate changes too much (fr1/rpy at 15 Hz, 30 frames: ATE
# 2.8 -> 4.9 cm with the correction; at 30 Hz the whole sequence 2.54 -> 1.92 cm), so such a frame
# is registered as it is, then corrected by its own measured rate and registered again
# (_measured_rate, _corrected_registration)
MAX_RATE_INTERVAL_S = 0.05
# a keypoint's localisation noise [px] as a share of the PnP inlier threshold (χ²₂ 95 %: 2.45 σ):
# a frame whose rolling-shutter skew is below it is not registered a second time
INLIER_THRESHOLD_SIGMAS = 2.45


class SlamSystem:
    """RGB-D SLAM. ``slam_map`` continues (or, with ``localisation_only``, localises in) a map
    loaded with :func:`raspv_slam.map_store.load_map` / :meth:`load`."""

    def __init__(self, intrinsics: CameraIntrinsics, config: SlamConfig | None = None,
                 slam_map: SlamMap | None = None, localisation_only: bool = False) -> None:
        self.config = config = config or (slam_map.config if slam_map is not None else SlamConfig())
        self.intrinsics = intrinsics
        if slam_map is not None and (slam_map.intrinsics.width, slam_map.intrinsics.height) != \
                (intrinsics.width, intrinsics.height):
            raise ValueError(f"the map was made with a {slam_map.intrinsics.width}x{slam_map.intrinsics.height} "
                             f"camera, this one is {intrinsics.width}x{intrinsics.height}")
        cv2.setNumThreads(config.threads)
        self.localisation_only = localisation_only
        self.preparer = FramePreparer(intrinsics, config)
        self.registrar = FrameRegistrar(intrinsics, self.preparer.small_intrinsics, config, self.preparer.registration,
                                        self.preparer.wide_registration)
        self.map = slam_map if slam_map is not None else SlamMap(intrinsics, config)
        self.loop_closer = None if localisation_only else LoopCloser(self.map, self.registrar, self.preparer, config)
        self.state = TrackingState.INITIALISING
        self.ref: int | None = None                  # reference keyframe
        self.ref_from_camera = np.eye(4)
        self.velocity = np.eye(4)                    # C_{k-1} ← C_k of the last tracked frames
        self._velocity_dt = 0.0                      # [s] between the frames of that motion
        self._previous_stamp: float | None = None
        self.failures = 0
        self.odom_from_camera = np.eye(4)
        self.map_from_odom = np.eye(4)
        self._loop_generation = self.map.loop_generation
        self.map_id = 0                              # the sub-map of the last result
        self.lost_since: float | None = None         # stamp at which tracking was lost [s]
        self._history: OrderedDict[float, tuple[int, np.ndarray]] = OrderedDict()
        self._last_tracked: tuple[Frame, int, np.ndarray] | None = None
        self._tracked_rotations: deque[tuple[float, np.ndarray]] = deque(maxlen=2)   # (stamp, O ← C rotation)
                                                     # of the last consecutive tracked frames: the measured rate
        self._first_keyframe: tuple[int, Frame, list] | None = None    # a map's first keyframe, made before any
                                                     # rate was known: (id, frame, its and the next frames' (stamp, O ← C))
        self._recent: deque[tuple[Frame, int, np.ndarray]] = deque(maxlen=config.keyframe_candidates)
        self._trajectory: list[tuple[float, int, np.ndarray]] = []     # every placed frame: stamp, ref, ref ← C
        self.counts = {"frames": 0, "tracked": 0, "predicted": 0, "lost": 0, "relocalised": 0, "loops": 0,
                       "to_last_frame": 0, "rolling_shutter_second_pass": 0, "first_keyframe_corrected": 0,
                       "new_maps": 0, "merges": 0}

    # -- per frame ----------------------------------------------------------------------------
    def process(self, stamp: float, rgb: np.ndarray | None, depth: np.ndarray | None) -> SlamResult:
        """One frame: colour (H, W, 3) uint8 RGB, depth (H, W) float32 metres (NaN = no
        reading); either may be None."""
        t0 = time.perf_counter()
        frame = self.preparer.prepare(float(stamp), rgb, depth, self._rotation_rate())
        self.counts["frames"] += 1
        loop_closed = self.map.loop_generation != self._loop_generation
        self._loop_generation = self.map.loop_generation
        inliers = 0
        if self.ref is None and len(self.map) == 0 and not self.localisation_only:
            state = self._initialise(frame)
        elif self.ref is None or self.state == TrackingState.LOST:
            state, inliers = self._relocalise(frame)
            if state == TrackingState.LOST and self._new_map_due(frame.stamp):
                state = self._start_new_map(frame)
        else:
            state, inliers = self._track(frame)
            if state == TrackingState.TRACKING and self._map_id_now() != self.map_id:
                state = TrackingState.MAP_MERGED      # tracked on: only a merge changes the sub-map
                self.counts["merges"] += 1
            elif state == TrackingState.TRACKING and loop_closed:
                state = TrackingState.LOOP_CLOSED
                self.counts["loops"] += 1
        if state == TrackingState.LOST and self.lost_since is None:
            self.lost_since = frame.stamp
        elif state != TrackingState.LOST:
            self.lost_since = None
        self.state = state
        self._previous_stamp = frame.stamp
        self.map_id = self._map_id_now()
        map_from_camera = None
        if state not in (TrackingState.LOST, TrackingState.INITIALISING):
            slam_from_camera = self.map.pose(self.ref) @ self.ref_from_camera
            map_from_camera = self.map.world_from_camera(slam_from_camera)
            self.map_from_odom = map_from_camera @ inverse(self.odom_from_camera)
            self._history[float(stamp)] = (self.ref, self.ref_from_camera.copy())
            self._trajectory.append((float(stamp), self.ref, self.ref_from_camera.copy()))
            while len(self._history) > HISTORY:
                self._history.popitem(last=False)
        return SlamResult(float(stamp), state, map_from_camera, self.odom_from_camera.copy(),
                          self.map_from_odom.copy(), self.ref, inliers, (time.perf_counter() - t0) * 1e3,
                          self.map_id)

    def _rotation_rate(self) -> np.ndarray | None:
        """The motion model's rotation rate ω (3,) in C [rad/s] while tracking (rolling-shutter
        correction), else None."""
        if self.config.rolling_shutter_readout <= 0 or self.state not in (
                TrackingState.TRACKING, TrackingState.LOOP_CLOSED, TrackingState.MAP_MERGED) \
                or not 0 < self._velocity_dt <= MAX_RATE_INTERVAL_S:
            return None
        # velocity = C_{k-1} ← C_k over _velocity_dt: C_t ← C_{t+τ} = exp(τ/dt · log velocity)
        return cv2.Rodrigues(np.ascontiguousarray(self.velocity[:3, :3]))[0].ravel() / self._velocity_dt

    def _initialise(self, frame: Frame) -> TrackingState:
        if not frame.has_depth or len(frame.features.with_depth) < self.config.min_inliers:
            return TrackingState.INITIALISING
        self.ref = self._add_keyframe(frame, np.eye(4), None, None)
        self.ref_from_camera = np.eye(4)
        self._tracked_rotations.append((frame.stamp, self.odom_from_camera[:3, :3].copy()))
        self._await_rate(frame)
        self.counts["tracked"] += 1
        return TrackingState.TRACKING

    def _track(self, frame: Frame) -> tuple[TrackingState, int]:
        c = self.config
        ref_from_previous = self.ref_from_camera
        predicted = ref_from_previous @ self.velocity
        ref_from_camera, reg, to_last = self._register_to_reference(frame, predicted, ref_from_previous)
        if ref_from_camera is not None and not self._plausible(ref_from_previous, ref_from_camera):
            ref_from_camera = None
        if ref_from_camera is not None:
            second = self._corrected_registration(frame, ref_from_previous, ref_from_camera)
            if second is not None:
                frame, ref_from_camera, reg, to_last = second
        if ref_from_camera is None:
            self.failures += 1
            self._tracked_rotations.clear()
            self._first_keyframe = None                         # its rate is not measured: it stays as seen
            if self.failures >= c.lost_after:
                self.counts["lost"] += 1
                self.velocity = np.eye(4)
                return TrackingState.LOST, 0
            self.ref_from_camera = predicted                    # the motion model carries the pose
            self.odom_from_camera = self.odom_from_camera @ self.velocity
            self.counts["predicted"] += 1
            return TrackingState.TRACKING, 0
        delta = inverse(ref_from_previous) @ ref_from_camera
        self.counts["to_last_frame"] += to_last
        self.failures = 0
        self.velocity = delta
        self._velocity_dt = frame.stamp - self._previous_stamp if self._previous_stamp is not None else 0.0
        self.odom_from_camera = self.odom_from_camera @ delta
        self._tracked_rotations.append((frame.stamp, self.odom_from_camera[:3, :3].copy()))
        self._correct_first_keyframe(frame.stamp)
        self.ref_from_camera = ref_from_camera
        self.counts["tracked"] += 1
        self._recent.append((frame, self.ref, self.ref_from_camera))
        self._last_tracked = self._recent[-1]
        self._maybe_new_keyframe(frame)
        return TrackingState.TRACKING, reg.inliers

    def _register_to_reference(self, frame: Frame, predicted: np.ndarray, ref_from_previous: np.ndarray):
        """(ref ← camera or None, the registration, 1 if it was to the last tracked frame else 0).
        ``predicted``: the constant-velocity pose; ``ref_from_previous`` (zero motion) is a start too
        when PnP is not trusted (a turn that stops between two frames)."""
        reg = self.registrar.register(frame, self._keyframe(self.ref), predicted_target_from_source=predicted,
                                      other_starts=(ref_from_previous,))
        if reg.ok:
            return reg.target_from_source, reg, 0
        if self._last_tracked is not None:
            # fast motion took the view too far from the keyframe: register to the last tracked frame
            last, last_ref, last_ref_from_last = self._last_tracked
            ref_from_last = self.map.relative(self.ref, last_ref) @ last_ref_from_last
            last_from_ref = inverse(ref_from_last)
            reg = self.registrar.register(frame, last, predicted_target_from_source=last_from_ref @ predicted,
                                          other_starts=(last_from_ref @ ref_from_previous,))
            if reg.ok:
                return ref_from_last @ reg.target_from_source, reg, 1
        return None, reg, 0

    def _plausible(self, ref_from_previous: np.ndarray, ref_from_camera: np.ndarray) -> bool:
        dt, dr = motion_size(inverse(ref_from_previous) @ ref_from_camera)
        return dt <= self.config.max_frame_translation and dr <= self.config.max_frame_rotation_deg

    def _measured_rate(self, stamp: float, odom_from_camera: np.ndarray) -> np.ndarray | None:
        """This frame's rotation rate (3,) in C [rad/s] from its pose and the last tracked frames'
        (:func:`rotation_rate`), None without a tracked frame just before it."""
        if not self._tracked_rotations or not stamp > self._tracked_rotations[-1][0]:
            return None
        stamps = [t for t, _ in self._tracked_rotations] + [stamp]
        return rotation_rate(stamps, [R for _, R in self._tracked_rotations] + [odom_from_camera[:3, :3]])

    def _corrected_registration(self, frame: Frame, ref_from_previous: np.ndarray, ref_from_camera: np.ndarray):
        """A rolling-shutter frame registered as it was seen (no rate predicted for it: frames too far
        apart), corrected by the rate its pose and the last two measure and registered again from
        that pose: (corrected frame, ref ← camera, registration, to last frame), or None when no
        second pass is needed (a skew below a keypoint's noise) or it failed (the first pass stands)."""
        c = self.config
        if c.rolling_shutter_readout <= 0 or frame.rate is not None or frame.as_seen is None:
            return None
        omega = self._measured_rate(frame.stamp, self.odom_from_camera @ inverse(ref_from_previous) @ ref_from_camera)
        if omega is None or skew_px(omega, c.rolling_shutter_readout, self.intrinsics) \
                <= c.reprojection_px / INLIER_THRESHOLD_SIGMAS:
            return None
        corrected = self.preparer.corrected(frame, omega)
        again, reg, to_last = self._register_to_reference(corrected, ref_from_camera, ref_from_previous)
        if again is None or not self._plausible(ref_from_previous, again):
            return None
        self.counts["rolling_shutter_second_pass"] += 1
        return corrected, again, reg, to_last

    def _await_rate(self, frame: Frame) -> None:
        """A map's first keyframe (``self.ref``, made from ``frame``) is made before any rotation rate
        is known, so a rolling-shutter frame is stored as seen; remember it until the frames after it
        measure its rate (:meth:`_correct_first_keyframe`)."""
        self._first_keyframe = None
        if self.config.rolling_shutter_readout > 0 and frame.rate is None and frame.as_seen is not None:
            self._first_keyframe = (self.ref, frame, [(frame.stamp, self.odom_from_camera[:3, :3].copy())])

    def _correct_first_keyframe(self, stamp: float) -> None:
        """Once the two frames tracked after a map's first keyframe give its rotation rate (the
        second-order difference forward in time, :func:`rotation_rate` with time reversed), its
        keypoints and 3-D points are turned to mid-row time — its pose is the map's origin, not a
        registration, so it stays. Its images stay as seen, as a frame corrected by a measured rate
        keeps them (:meth:`FramePreparer.corrected`; re-sampling them too was worse). Without this the first keyframe kept the skew of a camera
        already turning, and every frame registered to it inherited it (fr1/rpy's pan at 10 Hz: the
        floor point 5.5 → 4.8 cm at most, 5.2 → 4.5 cm at the return). Only for frames more than
        ``MAX_RATE_INTERVAL_S`` apart, where later frames are corrected by a measured rate too: over
        33-ms steps the extrapolated rate is too noisy for the keyframe every frame registers to
        (fr1/rpy at 30 Hz, on the loop closer's local window: online ATE 2.09 → 2.30 cm)."""
        if self._first_keyframe is None:
            return
        kf_id, frame, samples = self._first_keyframe
        samples.append((stamp, self.odom_from_camera[:3, :3].copy()))
        if samples[1][0] - samples[0][0] <= MAX_RATE_INTERVAL_S:
            self._first_keyframe = None         # a 30-Hz camera: see the docstring
            return
        if len(samples) < 3:
            return
        self._first_keyframe = None
        omega = -rotation_rate([-t for t, _ in reversed(samples)], [R for _, R in reversed(samples)])
        c = self.config
        if skew_px(omega, c.rolling_shutter_readout, self.intrinsics) <= c.reprojection_px / INLIER_THRESHOLD_SIGMAS:
            return
        self.map.replace_features(kf_id, self.preparer.corrected(frame, omega).features)
        self.counts["first_keyframe_corrected"] += 1

    def _maybe_new_keyframe(self, frame: Frame) -> None:
        c = self.config
        dt, dr = motion_size(self.ref_from_camera)
        if (dt <= c.keyframe_translation and dr <= c.keyframe_rotation_deg
                and self._view_overlap(self.ref, self.ref_from_camera) >= c.keyframe_overlap):
            return
        slam_from_camera = self.map.pose(self.ref) @ self.ref_from_camera
        for kf_id in self.map.nearby(slam_from_camera, c.reuse_radius, c.reuse_angle_deg, exclude={self.ref},
                                     segment=self.map.segment_of(self.ref))[:3]:
            kf_from_camera = inverse(self.map.pose(kf_id)) @ slam_from_camera
            if self._view_overlap(kf_id, kf_from_camera) < c.keyframe_overlap:
                continue
            reg = self.registrar.register(frame, self._keyframe(kf_id), predicted_target_from_source=kf_from_camera)
            if reg.ok and self._view_overlap(kf_id, reg.target_from_source) >= c.keyframe_overlap:
                self.ref, self.ref_from_camera = kf_id, reg.target_from_source
                return
        # the sharpest recent frame tracked against the same reference becomes the keyframe
        usable = [(f.sharpness, i) for i, (f, ref, _) in enumerate(self._recent)
                  if ref == self.ref and f.has_depth and len(f.features.with_depth) >= c.min_inliers]
        if not usable:
            # a view without features (a blank wall) tracked densely: a keyframe of its depth and
            # colour, so the reference follows the camera instead of going stale as it turns
            usable = [(f.sharpness, i) for i, (f, ref, _) in enumerate(self._recent) if ref == self.ref and f.has_depth]
        if not usable:
            return
        best, ref, ref_from_best = self._recent[max(usable)[1]]      # ref is self.ref
        seen = self.map.pose(ref)
        self.ref = self._add_keyframe(best, seen @ ref_from_best, ref, ref_from_best, parent_pose_seen=seen)
        self.ref_from_camera = inverse(ref_from_best) @ self.ref_from_camera    # relative: no map pose read
        self._recent.clear()

    def _view_overlap(self, kf_id: int, kf_from_camera: np.ndarray) -> float:
        """Share of a keyframe's view a camera at ``kf_from_camera`` still sees: its 3-D feature
        points, or for a keyframe with too few of them (a blank wall) its depth probe points."""
        if len(self.map.keyframes[kf_id].features.with_depth) >= self.config.min_inliers:
            return self.map.view_overlap(kf_id, kf_from_camera)
        p = self._keyframe(kf_id).probe_points(self.preparer.small_intrinsics)
        if not len(p):
            return 0.0
        camera_from_kf = inverse(kf_from_camera)
        q = p @ camera_from_kf[:3, :3].T + camera_from_kf[:3, 3]
        K = self.preparer.small_intrinsics
        u, v, z = K.project(q)
        return float(((z > self.config.min_depth) & K.contains(u, v)).mean())

    def _relocalise(self, frame: Frame) -> tuple[TrackingState, int]:
        c = self.config
        found = None
        for kf_id, _score in self.map.places.query(frame.features.descriptors, c.loop_candidates):
            reg = self.registrar.register(frame, self._keyframe(kf_id), min_inliers=c.relocalise_min_inliers)
            if reg.ok and reg.inliers >= c.relocalise_min_inliers and (found is None or reg.inliers > found[1].inliers):
                found = (kf_id, reg)
        if found is None:
            return (TrackingState.INITIALISING if self.ref is None else TrackingState.LOST), 0
        self.ref, self.ref_from_camera = found[0], found[1].target_from_source
        self.velocity = np.eye(4)
        self._tracked_rotations.clear()
        self.failures = 0
        self.counts["relocalised"] += 1
        return TrackingState.RELOCALISED, found[1].inliers

    def _map_id_now(self) -> int:
        return self.map.segment_of(self.ref) if self.ref is not None else self.map_id

    def _new_map_due(self, stamp: float) -> bool:
        """Lost for ``new_map_after`` seconds (by frame stamps) while mapping."""
        after = self.config.new_map_after
        return (not self.localisation_only and after > 0 and self.lost_since is not None
                and stamp - self.lost_since >= after)

    def _start_new_map(self, frame: Frame) -> TrackingState:
        """A new sub-map with this frame as its first keyframe, in a frame of its own: S_j is
        placed so the camera is where the last tracked pose left it (``map_from_odom`` does not
        jump; the motion while lost is unknown). LOST when the frame cannot start a map."""
        if not frame.has_depth or len(frame.features.with_depth) < self.config.min_inliers:
            return TrackingState.LOST
        with self.map.lock:
            slam_from_map = inverse(self.map.world_from_slam)
        segment = self.map.new_segment()
        self.ref = self._add_keyframe(frame, slam_from_map @ self.map_from_odom @ self.odom_from_camera, None, None,
                                      segment=segment)
        self.ref_from_camera = np.eye(4)
        self.velocity = np.eye(4)
        self._tracked_rotations.clear()
        self._await_rate(frame)
        self.failures = 0
        self._last_tracked = None
        self._recent.clear()
        self.counts["new_maps"] += 1
        self.counts["tracked"] += 1
        return TrackingState.NEW_MAP

    def _add_keyframe(self, frame: Frame, slam_from_camera: np.ndarray, parent: int | None,
                      parent_from_kf: np.ndarray | None, parent_pose_seen: np.ndarray | None = None,
                      segment: int | None = None) -> int:
        color, depth = encode_images(frame.small_rgb, frame.small_depth)
        kf = Keyframe(self.map.new_id(), frame.stamp, frame.features, color, depth)
        if self.localisation_only:
            # outside the mapped views: a transient keyframe to track against (never saved, not a
            # place to relocalise in; the oldest are dropped)
            self.map.add_keyframe(kf, slam_from_camera, transient=True,
                                  segment=self.map.segment_of(parent) if parent is not None else 0)
            keep = {parent} | ({self._last_tracked[1]} if self._last_tracked is not None else set())
            self.map.prune_transient(TRANSIENT_KEYFRAMES, keep=keep)
            return kf.id
        self.map.add_keyframe(kf, slam_from_camera, parent, parent_from_kf, parent_pose_seen=parent_pose_seen,
                              segment=segment)
        self.loop_closer.submit(kf.id)
        return kf.id

    def _keyframe(self, kf_id: int) -> Frame:
        return self.map.frame(kf_id, self.preparer.keyframe_frame)

    # -- the map frame ------------------------------------------------------------------------
    def anchor_to_floor(self, floor_plane: np.ndarray, stamp: float) -> None:
        """Make M gravity-aligned from a floor (a, b, c, d), normal up, seen in the camera frame of
        the frame with that stamp (z up, z = 0 on the floor, x along the first keyframe's view
        direction; RGBDOdometry.anchor_to_floor's frame). A map already anchored (or a loaded
        one) keeps its frame; a stamp no longer (or never) tracked raises ValueError."""
        if self.map.anchored or self.localisation_only:
            return
        key = min(self._history, key=lambda s: abs(s - stamp), default=None)
        if key is None or abs(key - stamp) > STAMP_TOLERANCE_S:
            raise ValueError(f"no tracked frame with stamp {stamp:.3f}")
        ref, ref_from_camera = self._history[key]
        if self.map.segment_of(ref) != 0:
            raise ValueError(f"the frame with stamp {stamp:.3f} is in a new map not merged into the first one")
        self.map.anchor(world_from_floor_plane(np.asarray(floor_plane, np.float64), self.map.pose(ref) @ ref_from_camera))

    # -- the map ------------------------------------------------------------------------------
    def snapshot(self, max_landmarks: int = 5000, occupancy: bool = True) -> MapSnapshot:
        """The map now; ``occupancy=False`` leaves the floor occupancy out (None): it is made from
        every keyframe's depth, seconds on a large map, and the node's markers do not draw it."""
        from raspv_slam.floor_occupancy import floor_occupancy

        permanent = set(self.map.permanent)
        poses = {k: p for k, p in self.map.poses().items() if k in permanent}
        with self.map.lock:
            world_from_slam = self.map.world_from_slam.copy()
            edges = list(self.map.edges)
            keyframes = {k: kf for k, kf in self.map.keyframes.items() if k in permanent}
        per_kf = max(1, max_landmarks // max(1, len(keyframes)))
        points = []
        for k, kf in keyframes.items():
            p = kf.features.points[kf.features.with_depth][:per_kf].astype(np.float64)
            T = world_from_slam @ poses[k]
            points.append(p @ T[:3, :3].T + T[:3, 3])
        landmarks = np.concatenate(points) if points else np.zeros((0, 3))
        grid = floor_occupancy(self.map) if occupancy and self.map.anchored else None
        return MapSnapshot({k: world_from_slam @ p for k, p in poses.items()}, landmarks[:max_landmarks],
                           [(e.a, e.b) for e in edges if e.kind == "loop"], grid, self.map.anchored,
                           [(e.a, e.b) for e in edges if e.kind == "covisibility"])

    def trajectory(self) -> tuple[np.ndarray, np.ndarray]:
        """(stamps (N,), poses M ← C (N, 4, 4)) of every frame placed so far, relative to its
        reference keyframe's pose *now* (after every correction): the trajectory SLAM
        benchmarks evaluate (ORB-SLAM's SaveTrajectoryTUM). Frames in a new sub-map not merged
        into the first map are left out (their poses are in a frame of their own)."""
        if self.loop_closer is not None:
            self.loop_closer.wait_idle()
        poses = self.map.poses()
        with self.map.lock:
            world_from_slam = self.map.world_from_slam.copy()
        with self.map.lock:
            first_map = {k for k, seg in self.map.segment.items() if seg == 0}
        kept = [(t, ref, rel) for t, ref, rel in self._trajectory
                if ref in poses and ref in first_map]            # localisation drops transients
        stamps = np.array([t for t, _, _ in kept])
        out = np.array([world_from_slam @ poses[ref] @ rel for _, ref, rel in kept]).reshape(-1, 4, 4)
        return stamps, out

    def save(self, path: str | Path, wait_for_loops_s: float | None = None) -> None:
        """Write the map into the folder ``path`` (see :mod:`raspv_slam.map_store`), after the loop
        closer has processed its keyframes (waiting at most ``wait_for_loops_s`` [s]; None: until
        it has; the map is consistent either way, keyframes not processed yet are saved as tracking
        placed them). Safe while another thread tracks (the map is copied under its lock). A map
        loaded for localisation is never written (ValueError)."""
        from raspv_slam.map_store import save_map

        if self.localisation_only:
            raise ValueError("a map loaded for localisation is not saved: it stays as it is on disk")
        if self.loop_closer is not None:
            self.loop_closer.wait_idle(wait_for_loops_s)
        save_map(self.map, path)

    @classmethod
    def load(cls, path: str | Path, intrinsics: CameraIntrinsics, config: SlamConfig | None = None,
             localisation_only: bool = True, run_settings: dict | None = None) -> "SlamSystem":
        """A system on a saved map (a folder, or a name in the maps directory), run with ``config``
        (default: the settings the map was built with) with ``run_settings`` replacing some of
        them: the runner's choices, not the map's (e.g. ``{"new_map_after": 0.0, "threads": 2}``)."""
        from raspv_slam.map_store import load_map

        slam_map = load_map(path, config)
        if run_settings:
            config = replace(slam_map.config, **run_settings)
        return cls(intrinsics, config, slam_map, localisation_only)

    def close(self) -> None:
        """Stop the background thread (pending keyframes are processed first)."""
        if self.loop_closer is not None:
            self.loop_closer.stop()

    def __enter__(self) -> "SlamSystem":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def tracked_share(self) -> float:
        n = self.counts["frames"]
        return math.nan if not n else (self.counts["tracked"] + self.counts["relocalised"]) / n
