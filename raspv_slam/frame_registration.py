"""The relative pose of two frames: ORB matches + PnP RANSAC, refined by dense RGB-D
registration and verified by depth agreement (no ROS). Tracking, covisibility and loop edges
and relocalisation all use it.

Conventions: ``target ← source`` maps points of the source camera frame into the target's; the
target is usually a keyframe (its features carry 3-D points), the source the frame being placed.

1. Source descriptors are matched to the target's features that have depth (ratio test);
   ``cv2.solvePnPRansac`` (AP3P minimal sets, the config's inlier threshold) then
   Levenberg-Marquardt on the inliers gives a first pose. PnP alone confuses a small rotation
   with a translation when the points are far and noisy (blur, coarse pyramid levels): it is a
   starting point.
2. The dense registration (``raspv_perception``'s Open3D hybrid odometry, half-size images)
   refines it. When PnP failed, or its result does not pass verification (3.), the dense
   registration also starts from the predicted pose (motion model, the current map), then from
   the caller's ``other_starts`` (the tracker's zero-motion pose); the first start whose result
   verifies wins. When a prediction is given and PnP found too few inliers to be trusted, its
   pose (from ``PNP_START_INLIERS`` inliers) is still the first start. Starts other than a
   trusted PnP pose are registered on a deeper pyramid (``dense_coarsest_px``): the motion model
   misses a turn that starts or stops between two frames by a whole frame's turn (8° at 10 Hz),
   and from there the three-level registration settled 19 cm / 6° off on a plain wall with the
   wall's depth agreeing (depth cannot see a slide along a plane).
3. Each result is verified: a grid of the source's depth points is moved into the target and
   compared with the target's depth there; a pose counts when at least ``min_agreement`` of
   the points that land on measured depth agree within the sensor's noise (3σ of the Kinect
   model σ_z = 1.42 mm·z², Khoshelham & Elberink 2012, plus 1 cm for registration of depth to
   colour), and at least ``min_inliers`` do. The verified result with most agreeing points wins.
"""
from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.rgbd_odometry import DenseRegistration
from raspv_slam.config import SlamConfig
from raspv_slam.features import DescriptorMatcher, Features
from raspv_slam.frame import Frame
from raspv_slam.se3 import from_rvec_tvec, inverse, motion_size

DEPTH_NOISE_Z2 = 1.42e-3      # σ_z / z² of structured-light depth [1/m] (Khoshelham & Elberink 2012)
DEPTH_SLACK = 0.01            # depth-to-colour registration and interpolation [m]
MIN_DENSE_FITNESS = 0.05      # share of the source's depth pixels the dense registration matched
PNP_START_INLIERS = 8         # a PnP pose with fewer inliers than trusted is still a start for the dense step
RECENT_MATCHES = 4            # descriptor matchings remembered per thread (a frame registered again after its
                              # rolling-shutter correction keeps its descriptors: the same matches)


@dataclass
class Registration:
    """``target_from_source`` None when it failed; ``inliers`` of PnP (0 without); ``agreeing``
    3-D points that agree with the target's depth and their ``agreement`` share; ``method``
    "pnp+dense", "dense", "pnp" (no depth to refine or verify with) or "failed"."""

    target_from_source: np.ndarray | None
    inliers: int
    agreeing: int
    agreement: float
    method: str

    @property
    def ok(self) -> bool:
        return self.target_from_source is not None


class FrameRegistrar:
    def __init__(self, intrinsics: CameraIntrinsics, small_intrinsics: CameraIntrinsics, config: SlamConfig,
                 dense: DenseRegistration, wide_dense: DenseRegistration | None = None) -> None:
        """``dense`` refines PnP starts; ``wide_dense`` (default ``dense``), a deeper pyramid, the others."""
        self.intrinsics = intrinsics
        self.small = small_intrinsics
        self.config = config
        self.dense = dense
        self.wide_dense = wide_dense or dense
        self.matcher = DescriptorMatcher(config)
        self._recent = threading.local()         # the loop closer's thread registers with this registrar too

    def match(self, source: Features, target: Features) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(source indices, target indices, the target's indices with depth): ``source``'s
        descriptors matched to those of ``target``'s features that have a 3-D point; the last few
        matchings are reused for the same target and the same source descriptors (a source's
        keypoints moved by a correction keep their descriptors)."""
        recent = getattr(self._recent, "matches", None)
        if recent is None:
            recent = self._recent.matches = deque(maxlen=RECENT_MATCHES)
        for src, tgt, found in recent:
            if src is source.descriptors and tgt is target:
                return found
        idx3d = target.with_depth
        qi, ti = self.matcher.match(source.descriptors, target.descriptors[idx3d])
        recent.append((source.descriptors, target, (qi, ti, idx3d)))
        return qi, ti, idx3d

    def pnp(self, source: Features, target: Features, min_inliers: int) -> tuple[np.ndarray | None, int]:
        """(target ← source from PnP, inliers), (None, inliers) when it failed."""
        if len(source) < min_inliers or len(target.with_depth) < min_inliers:
            return None, 0
        qi, ti, idx3d = self.match(source, target)
        if len(qi) < min_inliers:
            return None, len(qi)
        obj = target.points[idx3d[ti]].astype(np.float64)
        img = source.keypoints[qi].astype(np.float64)
        K = self.intrinsics.K
        ok, rvec, tvec, inl = cv2.solvePnPRansac(obj, img, K, None, iterationsCount=200,
                                                 reprojectionError=self.config.reprojection_px, confidence=0.999,
                                                 flags=cv2.SOLVEPNP_AP3P)
        if not ok or inl is None or len(inl) < min_inliers:
            return None, 0 if inl is None else len(inl)
        inl = inl.ravel()
        rvec, tvec = cv2.solvePnPRefineLM(obj[inl], img[inl], K, None, rvec, tvec)
        proj, _ = cv2.projectPoints(obj, rvec, tvec, K, None)
        inliers = int((np.linalg.norm(proj.reshape(-1, 2) - img, axis=1) < self.config.reprojection_px).sum())
        if inliers < min_inliers:
            return None, inliers
        return inverse(from_rvec_tvec(rvec, tvec)), inliers

    def agreement(self, source: Frame, target: Frame, target_from_source: np.ndarray) -> tuple[int, float]:
        """(source probe points agreeing with the target's depth, their share of the points
        landing on measured target depth)."""
        p = source.probe_points(self.small)
        if not len(p) or target.small_depth is None:
            return 0, 0.0
        q = p @ target_from_source[:3, :3].T + target_from_source[:3, 3]
        u, v, z = self.small.project(q)
        inside = (z > 0) & self.small.contains(u, v)
        if not inside.any():
            return 0, 0.0
        col = np.clip(np.rint(u[inside]).astype(int), 0, self.small.width - 1)
        row = np.clip(np.rint(v[inside]).astype(int), 0, self.small.height - 1)
        measured = target.small_depth[row, col]
        zin = z[inside]
        has = np.isfinite(measured)
        if not has.any():
            return 0, 0.0
        tol = 3.0 * DEPTH_NOISE_Z2 * zin[has] ** 2 + DEPTH_SLACK
        agree = int((np.abs(measured[has] - zin[has]) <= tol).sum())
        return agree, agree / int(has.sum())

    def register(self, source: Frame, target: Frame, min_inliers: int | None = None,
                 predicted_target_from_source: np.ndarray | None = None,
                 other_starts: tuple[np.ndarray, ...] = ()) -> Registration:
        """PnP, dense refinement and verification (see the module docstring). ``other_starts``:
        further target ← source guesses for the dense step, tried (last) only when PnP is not trusted."""
        c = self.config
        min_inliers = c.min_inliers if min_inliers is None else min_inliers
        # an untrusted PnP pose is a start only where a dense-only result is wanted (a prediction is given)
        weakest = min(min_inliers, PNP_START_INLIERS) if predicted_target_from_source is not None else min_inliers
        pose, inliers = self.pnp(source.features, target.features, weakest)
        trusted = pose is not None and inliers >= min_inliers
        if source.dense is None or target.dense is None:
            if not trusted:
                return Registration(None, inliers, 0, 0.0, "failed")
            return Registration(pose, inliers, 0, 0.0, "pnp")
        starts = [s for s in (pose, predicted_target_from_source) if s is not None]
        if not trusted:
            starts += list(other_starts)
        best: Registration | None = None
        for n, start in enumerate(starts):
            if n > 0 and best is not None:
                break                              # the first start that verified wins (PnP's first)
            dense = self.dense if n == 0 and trusted else self.wide_dense     # a start maybe a frame's motion off
            refined, fitness = dense.register(source.dense, target.dense, start,
                                              geometric_only=source.small_rgb is None or target.small_rgb is None)
            if fitness < MIN_DENSE_FITNESS:
                continue                           # no correspondences: Open3D hands the start back
            dt, dr = motion_size(inverse(start) @ refined)
            if dt > c.max_frame_translation or dr > c.max_frame_rotation_deg:
                continue                           # the registration ran away from its start
            agreeing, share = self.agreement(source, target, refined)
            if share >= c.min_agreement and agreeing >= min_inliers and (best is None or agreeing > best.agreeing):
                from_pnp = n == 0 and trusted
                best = Registration(refined, inliers if from_pnp else 0, agreeing, share,
                                    "pnp+dense" if from_pnp else "dense")
        if best is not None:
            return best
        return Registration(None, inliers, 0, 0.0, "failed")
