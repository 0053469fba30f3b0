"""One camera frame prepared for SLAM: rectified, ORB features with depth, a small copy for dense
registration (no ROS).

Input: colour (H, W, 3) uint8 RGB and depth (H, W) float32 metres registered to the colour
(NaN: no reading); either may be missing. With lens distortion coefficients in the config the
keypoints are undistorted (:mod:`features`) and the small images for dense registration are
rectified (maps precomputed; depth by nearest neighbour), so every later step sees a pinhole
camera.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.rgbd_odometry import DenseImage, DenseRegistration, OdometryConfig
from raspv_slam.config import SlamConfig
from raspv_slam.features import FeatureExtractor, Features
from raspv_slam.rolling_shutter import correct_features, correct_images

PROBE_STRIDE = 8            # px of the small (dense-registration) image between verification points


@dataclass
class Frame:
    stamp: float
    features: Features
    small_rgb: np.ndarray | None        # (h, w, 3) uint8 at config.dense_scale (None without colour)
    small_depth: np.ndarray | None      # (h, w) float32 metres, NaN = no reading (None without depth)
    dense: DenseImage | None            # for dense registration (None without depth)
    rate: np.ndarray | None = None      # the rotation rate (3,) in C [rad/s] it was corrected to mid-row time by
    as_seen: tuple | None = field(default=None, repr=False)   # a rolling-shutter frame's (features, small
                                        # colour, small depth) before any correction (FramePreparer.corrected)
    _probe: np.ndarray | None = field(default=None, repr=False)
    _sharpness: float | None = field(default=None, repr=False)

    @property
    def has_depth(self) -> bool:
        return self.small_depth is not None

    @property
    def sharpness(self) -> float:
        """Variance of the Laplacian of the small grey image (blur lowers it; 0 without colour).
        Computed when first asked: only the frames a keyframe is chosen among need it."""
        if self._sharpness is None:
            self._sharpness = 0.0 if self.small_rgb is None else \
                float(cv2.Laplacian(cv2.cvtColor(self.small_rgb, cv2.COLOR_RGB2GRAY), cv2.CV_32F).var())
        return self._sharpness

    def probe_points(self, intrinsics: CameraIntrinsics) -> np.ndarray:
        """3-D points (N, 3) in C on a regular grid of the small depth image (every
        ``PROBE_STRIDE``-th pixel with a reading): what registrations are verified with."""
        if self._probe is None:
            if self.small_depth is None:
                self._probe = np.zeros((0, 3))
            else:
                v, u = np.mgrid[PROBE_STRIDE // 2:intrinsics.height:PROBE_STRIDE,
                                PROBE_STRIDE // 2:intrinsics.width:PROBE_STRIDE]
                z = self.small_depth[v, u].ravel()
                ok = np.isfinite(z)
                self._probe = intrinsics.rays(u.ravel()[ok], v.ravel()[ok]) * z[ok, None]
        return self._probe


def pyramid_iterations(finest: tuple[int, ...], width: int, coarsest_px: int) -> tuple[int, ...]:
    """Iterations per level of a dense registration's pyramid, coarse to fine: as many levels as
    halve ``width`` [px] down to the last one at least ``coarsest_px`` wide, and never fewer than
    ``finest`` has; the finest levels take ``finest``, the coarser ones its first value."""
    levels = 1
    while width / 2 ** levels >= coarsest_px:
        levels += 1
    finest = tuple(int(i) for i in finest)
    return (finest[0],) * max(0, levels - len(finest)) + finest


class FramePreparer:
    """Turns raw images into :class:`Frame` s for one camera."""

    def __init__(self, intrinsics: CameraIntrinsics, config: SlamConfig) -> None:
        self.intrinsics = intrinsics
        self.config = config
        w = max(8, int(round(intrinsics.width * config.dense_scale)))
        h = max(8, int(round(intrinsics.height * config.dense_scale)))
        self.small_intrinsics = intrinsics.scaled(w, h)
        self.extractor = FeatureExtractor(intrinsics, config)
        self.registration = DenseRegistration(OdometryConfig(
            scale=1.0, threads=config.threads, min_depth=config.min_depth, max_depth=config.max_depth,
            iterations=tuple(config.dense_iterations)))
        # for starts far from the answer (not from PnP): the same registration on a deeper pyramid
        self.wide_registration = DenseRegistration(replace(
            self.registration.config, iterations=pyramid_iterations(config.dense_iterations, w, config.dense_coarsest_px)))
        self._maps = None
        if config.distortion:
            K = self.small_intrinsics
            self._maps = cv2.initUndistortRectifyMap(K.K, np.asarray(config.distortion, np.float64), None, K.K,
                                                     (K.width, K.height), cv2.CV_16SC2)

    def check(self, rgb: np.ndarray | None, depth: np.ndarray | None) -> None:
        K = self.intrinsics
        if rgb is not None and (rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8
                                or rgb.shape[:2] != (K.height, K.width)):
            raise ValueError(f"colour must be a {K.width}x{K.height} RGB uint8 image (H, W, 3), "
                             f"got {rgb.dtype} {rgb.shape}")
        if depth is not None and (depth.ndim != 2 or not np.issubdtype(depth.dtype, np.floating)
                                  or depth.shape != (K.height, K.width)):
            raise ValueError(f"depth must be a {K.width}x{K.height} float image in metres, got {depth.dtype} {depth.shape}")

    def prepare(self, stamp: float, rgb: np.ndarray | None, depth: np.ndarray | None,
                omega: np.ndarray | None = None) -> Frame:
        """``omega``: the camera's rotation rate (3,) in C [rad/s] the motion model predicts; with
        the config's ``rolling_shutter_readout`` the frame is corrected to its mid-row time
        (:mod:`rolling_shutter`). A frame of a rolling-shutter camera keeps what it was made of,
        so :meth:`corrected` can turn it by another rate later without extracting it again."""
        self.check(rgb, depth)
        if depth is not None:
            depth = np.asarray(depth, dtype=np.float32)
        features = Features.empty()
        if rgb is not None:
            features = self.extractor.extract(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), depth)
        size = (self.small_intrinsics.width, self.small_intrinsics.height)
        small_rgb = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA) if rgb is not None else None
        small_depth = cv2.resize(depth, size, interpolation=cv2.INTER_NEAREST) if depth is not None else None
        if self._maps is not None:
            if small_rgb is not None:
                small_rgb = cv2.remap(small_rgb, *self._maps, cv2.INTER_LINEAR)
            if small_depth is not None:
                small_depth = cv2.remap(small_depth, *self._maps, cv2.INTER_NEAREST, borderValue=float("nan"))
        if self.config.rolling_shutter_readout > 0 and rgb is not None:
            as_seen = (features, small_rgb, small_depth)
            if omega is not None:
                return self._corrected(stamp, as_seen, omega)
            return self._frame(stamp, features, small_rgb, small_depth, as_seen=as_seen)
        return self._frame(stamp, features, small_rgb, small_depth)

    def corrected(self, frame: Frame, omega: np.ndarray) -> Frame:
        """``frame`` (made by :meth:`prepare` for a rolling-shutter camera without a rate) with its
        keypoints and their 3-D points turned to mid-row time by the rotation rate ``omega`` (3,)
        in C [rad/s] measured after its first registration; its small images stay as seen (with the
        measured rate the re-sampled images made the 10 Hz tracking worse: fr1/rpy ATE 2.5 -> 3.9
        cm, docs/slam.md). ValueError for a frame that kept nothing to correct."""
        if frame.as_seen is None:
            raise ValueError("this frame cannot be corrected (no rolling-shutter readout, or no colour)")
        features = frame.as_seen[0]
        if len(features):
            uv, points = correct_features(features.keypoints, features.points, features.keypoints[:, 1] + 0.5,
                                          self.intrinsics, omega, self.config.rolling_shutter_readout)
            features = Features(uv, features.descriptors, points, features.octaves)
        return Frame(frame.stamp, features, frame.small_rgb, frame.small_depth, frame.dense,
                     rate=np.asarray(omega, np.float64), as_seen=frame.as_seen, _sharpness=frame._sharpness)

    def _corrected(self, stamp: float, as_seen: tuple, omega: np.ndarray) -> Frame:
        features, small_rgb, small_depth = as_seen
        readout = self.config.rolling_shutter_readout
        if len(features):
            uv, points = correct_features(features.keypoints, features.points, features.keypoints[:, 1] + 0.5,
                                          self.intrinsics, omega, readout)
            features = Features(uv, features.descriptors, points, features.octaves)
        small_rgb, small_depth = correct_images(small_rgb, small_depth, self.small_intrinsics, omega, readout)
        return self._frame(stamp, features, small_rgb, small_depth, as_seen=as_seen,
                           rate=np.asarray(omega, np.float64))

    def _frame(self, stamp: float, features: Features, small_rgb: np.ndarray | None,
               small_depth: np.ndarray | None, as_seen: tuple | None = None,
               rate: np.ndarray | None = None) -> Frame:
        dense = self.dense_image(small_rgb, small_depth) if small_depth is not None else None
        return Frame(stamp, features, small_rgb, small_depth, dense, rate=rate, as_seen=as_seen)

    def keyframe_frame(self, kf) -> Frame:
        """A keyframe as a :class:`Frame` to register against (its images decoded)."""
        small_rgb, small_depth = kf.images()
        return Frame(kf.stamp, kf.features, small_rgb, small_depth, self.dense_image(small_rgb, small_depth))

    def dense_image(self, small_rgb: np.ndarray | None, small_depth: np.ndarray) -> DenseImage:
        """The dense-registration image of a small colour/depth pair (a grey image stands in for
        missing colour: the registration is then geometric only)."""
        if small_rgb is None:
            small_rgb = np.full(small_depth.shape + (3,), 128, np.uint8)
        return self.registration.prepare(small_rgb, small_depth, self.small_intrinsics)
