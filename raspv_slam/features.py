"""ORB features with depth, and matching them (no ROS).

ORB (Rublee et al. 2011) as ORB-SLAM2 uses it on RGB-D frames: 1000 keypoints over an 8-level
pyramid (scale 1.2); where the FAST threshold finds too few (motion blur), a second pass with
ORB-SLAM's lower threshold (7). Each keypoint gets the depth under it (nearest pixel of the
registered depth image) and so a 3-D point in the camera frame C (x right, y down, z forward,
metres), NaN where there is no reading in [min_depth, max_depth].
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_slam.config import SlamConfig

LOW_FAST_THRESHOLD = 7          # ORB-SLAM2's minThFAST, for frames where the default finds too few


@dataclass
class Features:
    """Keypoints (N, 2) px, descriptors (N, 32) uint8, 3-D points (N, 3) in C (NaN: no depth),
    pyramid octaves (N,)."""

    keypoints: np.ndarray
    descriptors: np.ndarray
    points: np.ndarray
    octaves: np.ndarray

    def __len__(self) -> int:
        return len(self.keypoints)

    @property
    def with_depth(self) -> np.ndarray:
        """Indices of the features that have a 3-D point."""
        return np.flatnonzero(np.isfinite(self.points[:, 2]))

    @classmethod
    def empty(cls) -> "Features":
        return cls(np.zeros((0, 2), np.float32), np.zeros((0, 32), np.uint8), np.zeros((0, 3), np.float32),
                   np.zeros(0, np.int8))


class FeatureExtractor:
    """ORB keypoints and descriptors of a grey image, lifted to 3-D with the depth image. With
    lens distortion, keypoints are found on the raw image, their depth read there (the depth is
    registered to the raw colour image), and their coordinates undistorted (ORB-SLAM's way;
    cheaper than rectifying whole images)."""

    def __init__(self, intrinsics: CameraIntrinsics, config: SlamConfig) -> None:
        self.intrinsics = intrinsics
        self.config = config
        self._distortion = np.asarray(config.distortion, np.float64) if config.distortion else None
        self._orb = cv2.ORB_create(nfeatures=config.features, scaleFactor=config.scale_factor, nlevels=config.levels,
                                   fastThreshold=config.fast_threshold, edgeThreshold=19, patchSize=31)
        self._orb_low = cv2.ORB_create(nfeatures=config.features, scaleFactor=config.scale_factor,
                                       nlevels=config.levels, fastThreshold=LOW_FAST_THRESHOLD, edgeThreshold=19,
                                       patchSize=31)

    def extract(self, gray: np.ndarray, depth: np.ndarray | None) -> Features:
        keypoints, descriptors = self._orb.detectAndCompute(gray, None)
        if len(keypoints) < self.config.features // 2:
            keypoints, descriptors = self._orb_low.detectAndCompute(gray, None)
        if descriptors is None or not keypoints:
            return Features.empty()
        raw = np.array([k.pt for k in keypoints], dtype=np.float32)
        octaves = np.array([k.octave for k in keypoints], dtype=np.int8)
        uv = raw
        if self._distortion is not None:
            K = self.intrinsics.K
            uv = cv2.undistortPoints(raw.reshape(-1, 1, 2), K, self._distortion, P=K).reshape(-1, 2).astype(np.float32)
        return Features(uv, descriptors, self.lift(raw, uv, depth), octaves)

    def lift(self, raw: np.ndarray, uv: np.ndarray, depth: np.ndarray | None) -> np.ndarray:
        """3-D points in C of keypoints at raw pixels ``raw`` (N, 2) (where the depth is read)
        with undistorted pixels ``uv``; NaN where the depth has no usable reading."""
        K = self.intrinsics
        points = np.full((len(uv), 3), np.nan, dtype=np.float32)
        if depth is None or not len(uv):
            return points
        col = np.clip(np.rint(raw[:, 0]).astype(int), 0, K.width - 1)
        row = np.clip(np.rint(raw[:, 1]).astype(int), 0, K.height - 1)
        z = depth[row, col]
        ok = np.isfinite(z) & (z >= self.config.min_depth) & (z <= self.config.max_depth)
        z = z[ok]
        points[ok, 0] = (uv[ok, 0] - K.cx) / K.fx * z
        points[ok, 1] = (uv[ok, 1] - K.cy) / K.fy * z
        points[ok, 2] = z
        return points


class DescriptorMatcher:
    """Brute-force Hamming matching with Lowe's ratio test and an absolute distance bound.

    The two nearest train descriptors of each query come from ``cv2.batchDistance`` (what
    ``cv2.BFMatcher.knnMatch`` computes, as arrays: no ``DMatch`` object per pair), so the ratio
    test runs vectorised."""

    def __init__(self, config: SlamConfig) -> None:
        self.ratio = config.match_ratio
        self.max_distance = config.max_hamming

    def match(self, query: np.ndarray, train: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Index pairs (query indices, train indices) of the unambiguous matches, each train
        descriptor used at most once (the closest query wins)."""
        if len(query) < 2 or len(train) < 2:
            return np.zeros(0, int), np.zeros(0, int)
        dist, nearest = cv2.batchDistance(query, train, cv2.CV_32S, normType=cv2.NORM_HAMMING, K=2)
        d0, d1 = dist[:, 0], dist[:, 1]
        q = np.flatnonzero((d0 <= self.max_distance) & (d0 < self.ratio * d1))
        if not len(q):
            return np.zeros(0, int), np.zeros(0, int)
        t, d = nearest[q, 0].astype(int), d0[q]
        order = np.lexsort((d, t))                   # per train index, the closest first
        first = np.ones(len(order), bool)
        first[1:] = t[order][1:] != t[order][:-1]
        keep = order[first]
        return q[keep], t[keep]
