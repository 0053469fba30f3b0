"""Camera pose from RGB-D frames by frame-to-frame odometry (Open3D), for sources without a
pose (real cameras, recordings) (no ROS).

Each frame is registered to the previous one with Open3D's tensor RGB-D odometry
(``o3d.t.pipelines.odometry.rgbd_odometry_multi_scale``: photometric + geometric "hybrid" term,
coarse-to-fine, Open3D's default 10/5/3 iterations), optionally on downscaled images; the
motions are chained into C0 ← C, the pose relative to the first camera frame C0. (The legacy
``o3d.pipelines.odometry`` took 96 ms per 320×240 frame on one core here, the tensor one 21 ms;
drift figures for both at the loss parameters below.)

World frame W (REP 103: x, y horizontal, z up, metres) is anchored to C0:
- with the floor seen in some frame (``anchor_to_floor``): z along the floor normal (up),
  origin on the floor below C0's centre, x along C0's optical axis projected on the floor,
  y = z × x (left) — so W is gravity-aligned and z = 0 is the floor;
- otherwise C0 is assumed level: x = C0's optical axis, y = its −x (left), z = its −y (up),
  origin at C0's centre.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics

DEPTH_HUBER_M = 0.03       # Huber delta of the depth residual [m]: ~2 sigma of structured-light noise at 2-3 m
INTENSITY_HUBER = 0.1      # Huber delta of the intensity residual (intensities in [0, 1]; Open3D's default)

# W ← C0 for a level camera (columns: C0's x, y, z axes in W).
LEVEL_WORLD_FROM_CAMERA = np.array([[0.0, 0.0, 1.0, 0.0],
                                    [-1.0, 0.0, 0.0, 0.0],
                                    [0.0, -1.0, 0.0, 0.0],
                                    [0.0, 0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class OdometryConfig:
    scale: float = 0.5                    # images are resized by this before registration (speed)
    threads: int = 0                      # Open3D threads, process-wide (0: Open3D's default, all cores)
    min_depth: float = 0.2                # depth used for registration [m]
    max_depth: float = 4.0                # (Open3D's default; far Kinect depth is too noisy) [m]
    max_depth_difference: float = 0.07    # correspondences farther apart in depth are rejected [m]
    iterations: tuple[int, ...] = (10, 5, 3)   # per pyramid level, as Open3D's criteria list
    max_translation: float = 0.3          # a frame-to-frame motion larger than this is a failure [m]
    max_rotation_deg: float = 20.0        # (at ≥ 10 Hz nobody moves the head faster) [deg]
    min_overlap: float = 0.3              # fraction of the frame's depth pixels that must find a match

    def __post_init__(self) -> None:
        if not 0.05 <= self.scale <= 1.0:
            raise ValueError(f"scale must be in [0.05, 1], got {self.scale}")
        if not 0 <= self.min_depth < self.max_depth:
            raise ValueError(f"need 0 <= min_depth < max_depth, got {self.min_depth}, {self.max_depth}")
        if not 0 <= self.min_overlap <= 1:
            raise ValueError(f"min_overlap must be in [0, 1], got {self.min_overlap}")
        if self.max_depth_difference <= 0 or self.max_translation <= 0 or self.max_rotation_deg <= 0:
            raise ValueError("max_depth_difference, max_translation and max_rotation_deg must be positive")
        if self.threads < 0:
            raise ValueError(f"threads must be >= 0, got {self.threads}")
        if not self.iterations or any(int(i) < 1 for i in self.iterations):
            raise ValueError(f"iterations must be positive counts per pyramid level, got {self.iterations}")


@dataclass
class OdometryStep:
    """Result for one frame: ``tracked`` False when registration failed (the pose is then held);
    ``relative`` previous ← current camera motion (identity on failure or the first frame)."""

    tracked: bool
    world_from_camera: np.ndarray
    relative: np.ndarray


@dataclass(frozen=True)
class DenseImage:
    """An RGB-D frame prepared for :class:`DenseRegistration` (resized, depth clipped)."""

    image: object                 # open3d.t.geometry.RGBDImage, intensities in [0, 1], depth metres (0: none)
    intrinsics: object            # open3d.core.Tensor 3×3 of the resized image
    size: tuple[int, int]         # (width, height) of the full-size frame it came from


class DenseRegistration:
    """Dense RGB-D registration of two frames (Open3D tensor multi-scale odometry, hybrid
    photometric + geometric term, robust depth weights) — the registration :class:`RGBDOdometry`
    chains, and the refinement step of ``raspv_slam``'s tracker."""

    def __init__(self, config: OdometryConfig | None = None) -> None:
        from raspv_common.native_libs import ensure_libusb

        ensure_libusb()             # Open3D links libusb-1.0
        import open3d as o3d        # heavy: imported when registration is used

        self._o3d = o3d
        self.config = config or OdometryConfig()
        if self.config.threads > 0:
            o3d.utility.set_max_threads(int(self.config.threads))
        odometry = o3d.t.pipelines.odometry
        self._criteria = [odometry.OdometryConvergenceCriteria(int(i)) for i in self.config.iterations]
        # depth residuals beyond max_depth_difference are outliers; the depth Huber delta is about
        # the inlier noise (structured light: 0.6-1.4 cm at 2-3 m, Khoshelham 2012), so moving
        # people weigh little. Measured (simulated office walk of 1.25 m with people walking;
        # synthetic textureless room, 0.4 m / 14°): Open3D's default 0.05 m drifted 0.45 m on the
        # walk (room 2.4 cm / 0.9°); 0.03 m: 0.12 m (room 2.9 cm / 1.1°); 0.02 m: 0.14 m (room
        # 3.1 cm / 1.6°); the legacy odometry 0.30 m (room 2.5 cm / 0.9°).
        self._loss = odometry.OdometryLossParams(depth_outlier_trunc=self.config.max_depth_difference,
                                                 depth_huber_delta=min(DEPTH_HUBER_M, 0.5 * self.config.max_depth_difference),
                                                 intensity_huber_delta=INTENSITY_HUBER)

    def prepare(self, rgb: np.ndarray, depth: np.ndarray, K: CameraIntrinsics) -> DenseImage:
        """Colour (H, W, 3) uint8 and depth (H, W) float metres (NaN: no reading) → a frame to register."""
        o3d = self._o3d
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"colour must be an (H, W, 3) uint8 RGB image, got {rgb.dtype} {rgb.shape}")
        if depth.ndim != 2 or not np.issubdtype(depth.dtype, np.floating):
            raise ValueError(f"depth must be an (H, W) float image in metres, got {depth.dtype} {depth.shape}")
        if rgb.shape[:2] != depth.shape or depth.shape != (K.height, K.width):
            raise ValueError(f"colour {rgb.shape[1]}x{rgb.shape[0]}, depth {depth.shape[1]}x{depth.shape[0]} and "
                             f"camera {K.width}x{K.height} must have the same size")
        size = (K.width, K.height)
        s = self.config.scale
        if s != 1.0:
            w, h = max(8, int(round(K.width * s))), max(8, int(round(K.height * s)))
            rgb = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA)
            depth = cv2.resize(depth, (w, h), interpolation=cv2.INTER_NEAREST)
            K = K.scaled(w, h)
        d = np.where(np.isfinite(depth) & (depth >= self.config.min_depth) & (depth <= self.config.max_depth),
                     depth, 0.0).astype(np.float32)
        color = (rgb.astype(np.float32) * np.float32(1.0 / 255.0))        # intensities in [0, 1]
        image = o3d.t.geometry.RGBDImage(o3d.t.geometry.Image(o3d.core.Tensor(color)),
                                         o3d.t.geometry.Image(o3d.core.Tensor(d)))
        intr = o3d.core.Tensor(np.array([[K.fx, 0.0, K.cx], [0.0, K.fy, K.cy], [0.0, 0.0, 1.0]]), o3d.core.float64)
        return DenseImage(image, intr, size)

    def register(self, source: DenseImage, target: DenseImage, target_from_source: np.ndarray | None = None,
                 geometric_only: bool = False) -> tuple[np.ndarray, float]:
        """(target ← source motion 4×4, overlap: the matched fraction of the source's depth
        pixels), starting from ``target_from_source`` (identity by default); ``geometric_only``:
        depth alone (point-to-plane), for frames without colour. A registration that finds no
        correspondence gives (identity, 0.0); a non-finite result overlap 0."""
        o3d = self._o3d
        if source.size != target.size:
            raise ValueError(f"cannot register a {source.size[0]}x{source.size[1]} frame to a "
                             f"{target.size[0]}x{target.size[1]} one")
        init = np.eye(4) if target_from_source is None else nearest_rigid(target_from_source)
        methods = o3d.t.pipelines.odometry.Method
        method = methods.PointToPlane if geometric_only else methods.Hybrid
        try:
            result = o3d.t.pipelines.odometry.rgbd_odometry_multi_scale(
                source.image, target.image, source.intrinsics, o3d.core.Tensor(init), 1.0, self.config.max_depth,
                self._criteria, method, self._loss)
        except RuntimeError:                     # e.g. no correspondences at all
            return np.eye(4), 0.0
        T = result.transformation.numpy()
        if not np.isfinite(T).all():
            return np.eye(4), 0.0
        return nearest_rigid(T), float(result.fitness)


def nearest_rigid(T: np.ndarray) -> np.ndarray:
    """A copy of the 4×4 transform ``T`` with its rotation block replaced by the nearest rotation
    (SVD, determinant +1). Open3D composes its updates with the start by matrix products and
    hands a start's skew back; a tracker that chains registrations through a constant-velocity
    prediction (start = previous pose · last motion, whose inverse is taken as a transpose)
    amplifies round-off by about 1.5× a frame — measured on a simulated walk: 0.06° of false
    rotation after 50 frames tracked without features grew to 12° 12 frames later."""
    out = np.array(T, dtype=np.float64).reshape(4, 4)
    u, _, vt = np.linalg.svd(out[:3, :3])
    if np.linalg.det(u @ vt) < 0:
        u[:, 2] = -u[:, 2]
    out[:3, :3] = u @ vt
    out[3] = (0.0, 0.0, 0.0, 1.0)
    return out


def rotation_angle_deg(T: np.ndarray) -> float:
    """Angle of the rotation part of a 4×4 (or 3×3) transform [deg]."""
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(np.asarray(T)[:3, :3]) - 1) / 2))))


def world_from_floor_plane(floor_plane: np.ndarray, c0_from_floor_camera: np.ndarray | None = None) -> np.ndarray:
    """W ← C0 that makes W gravity-aligned from a floor plane (a, b, c, d), normal up, seen in
    the camera frame whose pose relative to C0 is ``c0_from_floor_camera`` (default: C0 itself):
    z along the floor normal, z = 0 on the floor below C0's centre, x along C0's optical axis
    projected on the floor, y = z × x."""
    T = np.eye(4) if c0_from_floor_camera is None else np.asarray(c0_from_floor_camera, dtype=np.float64)
    n = T[:3, :3] @ np.asarray(floor_plane[:3], dtype=np.float64)
    norm = np.linalg.norm(n)
    if not np.isfinite(norm) or norm == 0:
        raise ValueError("floor plane normal must be a finite non-zero vector")
    n /= norm
    d = float(floor_plane[3]) / norm - float(n @ T[:3, 3])           # plane n·p + d = 0 in C0
    x = np.array([0.0, 0.0, 1.0]) - n[2] * n                         # C0's optical axis on the floor
    if np.linalg.norm(x) < 1e-6:
        x = np.array([0.0, -1.0, 0.0]) - n[1] * n
    x /= np.linalg.norm(x)
    y = np.cross(n, x)
    W = np.eye(4)
    W[:3, :3] = np.stack([x, y, n])      # rows: W axes in C0 → W ← C0 rotation
    W[:3, 3] = (0.0, 0.0, d)             # C0's centre is d above the floor, origin right below it
    return W


class RGBDOdometry:
    """Frame-to-frame RGB-D odometry. Feed frames in order with :meth:`process`."""

    def __init__(self, config: OdometryConfig | None = None) -> None:
        self.registration = DenseRegistration(config)
        self.config = self.registration.config
        self.reset()

    def reset(self) -> None:
        self._previous: DenseImage | None = None
        self.c0_from_camera = np.eye(4)
        self.world_from_c0 = LEVEL_WORLD_FROM_CAMERA.copy()
        self.anchored = False
        self.frames = 0
        self.failures = 0
        self.last_overlap = math.nan       # matched fraction of the last registration

    @property
    def world_from_camera(self) -> np.ndarray:
        return self.world_from_c0 @ self.c0_from_camera

    def process(self, rgb: np.ndarray, depth: np.ndarray, intrinsics: CameraIntrinsics) -> OdometryStep:
        """Register this frame (RGB uint8, depth metres with NaN holes) to the previous one."""
        image = self.registration.prepare(rgb, depth, intrinsics)
        relative = np.eye(4)
        tracked = True
        if self._previous is not None and self._previous.size == image.size:
            T, overlap = self.registration.register(image, self._previous)
            self.last_overlap = overlap
            if (overlap >= self.config.min_overlap and np.linalg.norm(T[:3, 3]) <= self.config.max_translation
                    and rotation_angle_deg(T) <= self.config.max_rotation_deg):
                relative = T                 # previous ← current
                self.c0_from_camera = self.c0_from_camera @ T
            else:
                tracked = False
                self.failures += 1
        self._previous = image
        self.frames += 1
        return OdometryStep(tracked, self.world_from_camera, relative)

    def anchor_to_floor(self, floor_plane: np.ndarray, c0_from_floor_camera: np.ndarray | None = None) -> None:
        """Make W gravity-aligned from a floor plane (a, b, c, d), normal up, seen in the camera
        frame whose pose relative to C0 is ``c0_from_floor_camera`` (default: C0 itself)."""
        self.world_from_c0 = world_from_floor_plane(floor_plane, c0_from_floor_camera)
        self.anchored = True
