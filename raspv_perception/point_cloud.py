"""Organised point clouds from depth images, surface normals and voxel downsampling (no ROS).

All geometry is in the camera optical frame C (x right, y down, z forward), metres. An
*organised* cloud keeps the image layout: sample (r, c) of a cloud built with ``stride`` s is
the depth pixel (r·s, c·s), so per-sample results map straight back to pixels.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics


class DepthInputError(ValueError):
    """A depth image that cannot be processed (wrong shape or type)."""


@dataclass
class OrganisedCloud:
    """Points sampled every ``stride`` pixels of an (H, W) depth image.

    ``points`` (h, w, 3) float32 metres in C, NaN where the depth is missing or out of range;
    ``valid`` (h, w) bool; ``footprint`` (h, w) float32: the area [m²] a sample stands for on a
    surface facing the camera, (s·z)²/(fx·fy); divide by |cos incidence| for the true area.
    """

    points: np.ndarray
    valid: np.ndarray
    footprint: np.ndarray
    stride: int
    image_shape: tuple[int, int]

    @property
    def shape(self) -> tuple[int, int]:
        return self.valid.shape

    def upsample(self, values: np.ndarray) -> np.ndarray:
        """Per-sample (h, w) values → (H, W) image at the depth resolution (nearest sample)."""
        H, W = self.image_shape
        s = self.stride
        values = np.asarray(values)
        h, w = values.shape[:2]
        if (values.ndim == 2 and values.dtype == np.uint8 and s > 1 and s & (s - 1) == 0
                and (h * s, w * s) == (H, W)):
            # Exact: with a power-of-two factor OpenCV's nearest source pixel is x // s.
            return cv2.resize(values, (W, H), interpolation=cv2.INTER_NEAREST)
        # Each sample repeated s × s times (the same as indexing rows and columns with
        # arange(H) // s and arange(W) // s, at a third of the cost).
        out = np.repeat(np.repeat(values, s, axis=0), s, axis=1)
        return out if out.shape[:2] == (H, W) else np.ascontiguousarray(out[:H, :W])


def as_depth_metres(depth: np.ndarray, intrinsics: CameraIntrinsics) -> np.ndarray:
    """Check a depth image against ``intrinsics`` and return it as float32 metres.

    Accepts float arrays (metres, NaN/inf/≤0 = no reading) and uint16 (millimetres, 0 = no
    reading). Raises :class:`DepthInputError` with the reason otherwise.
    """
    if not isinstance(depth, np.ndarray):
        raise DepthInputError(f"depth must be a numpy array, got {type(depth).__name__}")
    if depth.ndim != 2:
        raise DepthInputError(f"depth must be a single-channel (H, W) image, got shape {depth.shape}")
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise DepthInputError(f"depth is {depth.shape[1]}x{depth.shape[0]} but the camera model is "
                              f"{intrinsics.width}x{intrinsics.height}")
    if depth.dtype == np.uint16:
        out = depth.astype(np.float32) * np.float32(0.001)
        out[depth == 0] = np.nan
        return out
    if not np.issubdtype(depth.dtype, np.floating):
        raise DepthInputError(f"depth must be float metres or uint16 millimetres, got {depth.dtype}")
    return depth.astype(np.float32, copy=False)


def organised_cloud(depth: np.ndarray, intrinsics: CameraIntrinsics, stride: int = 2,
                    min_depth: float = 0.2, max_depth: float = 8.0) -> OrganisedCloud:
    """Back-project every ``stride``-th pixel of ``depth`` [m]; depth that is NaN, inf, ≤ 0 or
    outside [``min_depth``, ``max_depth``] gives NaN points (ignored downstream)."""
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    d = as_depth_metres(depth, intrinsics)[::stride, ::stride]
    with np.errstate(invalid="ignore"):
        valid = (d >= min_depth) & (d <= max_depth)
    z = np.where(valid, d, np.float32(np.nan)).astype(np.float32)
    u = (np.arange(0, intrinsics.width, stride, dtype=np.float32) - np.float32(intrinsics.cx)) / np.float32(intrinsics.fx)
    v = (np.arange(0, intrinsics.height, stride, dtype=np.float32) - np.float32(intrinsics.cy)) / np.float32(intrinsics.fy)
    pts = np.empty(z.shape + (3,), dtype=np.float32)
    pts[..., 0] = z * u[None, :]
    pts[..., 1] = z * v[:, None]
    pts[..., 2] = z
    footprint = np.where(valid, z * z * np.float32(stride * stride / (intrinsics.fx * intrinsics.fy)), 0.0).astype(np.float32)
    return OrganisedCloud(pts, valid, footprint, stride, (intrinsics.height, intrinsics.width))


def organised_normals(cloud: OrganisedCloud, step: int = 2, max_inverse_depth_bend: float = 0.03
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Unit surface normals (h, w, 3) in C pointing towards the camera, and their validity.

    Each normal is the cross product of the central differences ``step`` samples apart in the
    image rows and columns of a 3×3-smoothed cloud. A normal is invalid where a neighbour is
    missing or the surface bends or breaks: on a plane the inverse depth 1/z is affine in the
    image, so its second difference over ``step`` + 1 samples (the stencil and the smoothing)
    must stay below ``max_inverse_depth_bend`` [1/m] (depth-sensor noise is roughly constant
    in 1/z).
    """
    P = cloud.points
    valid = cloud.valid
    h, w = valid.shape
    normals = np.full((h, w, 3), np.nan, dtype=np.float32)
    ok = np.zeros((h, w), dtype=bool)
    k = int(step)
    if h <= 2 * k or w <= 2 * k:
        return normals, ok
    vf = valid.astype(np.float32)
    weight = cv2.boxFilter(vf, -1, (3, 3), normalize=False, borderType=cv2.BORDER_CONSTANT)
    with np.errstate(invalid="ignore", divide="ignore"):
        inv_weight = 1.0 / weight
    # Smoothed coordinates per channel (contiguous 2-D arrays are much faster than (h, w, 3)).
    sm = []
    for axis in range(3):
        ch = np.where(valid, P[..., axis], 0.0).astype(np.float32)
        with np.errstate(invalid="ignore"):
            sm.append(cv2.boxFilter(ch, -1, (3, 3), normalize=False, borderType=cv2.BORDER_CONSTANT) * inv_weight)
    rows, cols = slice(k, h - k), slice(k, w - k)
    du = [c[rows, 2 * k:] - c[rows, :w - 2 * k] for c in sm]
    dv = [c[2 * k:, cols] - c[:h - 2 * k, cols] for c in sm]
    nx = dv[1] * du[2] - dv[2] * du[1]
    ny = dv[2] * du[0] - dv[0] * du[2]
    nz = dv[0] * du[1] - dv[1] * du[0]
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    centre = P[rows, cols, :]
    facing = nx * centre[..., 0] + ny * centre[..., 1] + nz * centre[..., 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(facing > 0, -1.0, 1.0).astype(np.float32) / norm
    # Validity: 1/z nearly affine over the stencil widened by the smoothing radius (k + 1
    # samples each way), which also requires every sample there to be measured.
    j = k + 1
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.pad(1.0 / P[..., 2], 1, constant_values=np.nan)      # padded by one sample
        ic2 = 2.0 * inv[1 + k:h + 1 - k, 1 + k:w + 1 - k]
        good = np.abs(inv[1 + k:h + 1 - k, 1 + k + j:w + 1 - k + j] - ic2 + inv[1 + k:h + 1 - k, 1 + k - j:w + 1 - k - j]) < max_inverse_depth_bend
        good &= np.abs(inv[1 + k + j:h + 1 - k + j, 1 + k:w + 1 - k] - ic2 + inv[1 + k - j:h + 1 - k - j, 1 + k:w + 1 - k]) < max_inverse_depth_bend
        good &= norm > 0
    good &= valid[rows, cols]
    scale = np.where(good, scale, np.float32(np.nan))
    normals[rows, cols, 0] = nx * scale
    normals[rows, cols, 1] = ny * scale
    normals[rows, cols, 2] = nz * scale
    ok[k:h - k, k:w - k] = good
    return normals, ok


@dataclass
class VoxelGrid:
    """Points grouped by cubic voxels of edge ``size`` [m]: ``centroids`` (M, 3) mean point per
    occupied voxel, ``counts`` (M,) points per voxel, ``inverse`` (N,) voxel index of each input
    point (so per-voxel results map back to the points)."""

    size: float
    centroids: np.ndarray
    counts: np.ndarray
    inverse: np.ndarray


def voxel_downsample(points: np.ndarray, size: float) -> VoxelGrid:
    """Group finite points (N, 3) [m] into voxels of edge ``size`` [m] (no NaN allowed)."""
    if size <= 0:
        raise ValueError(f"voxel size must be positive, got {size}")
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    if len(pts) == 0:
        return VoxelGrid(size, np.zeros((0, 3), np.float32), np.zeros(0, np.int64), np.zeros(0, np.int64))
    idx = np.floor(pts / np.float32(size)).astype(np.int64)
    # Per-column extremes: reducing an (N, 3) array along axis 0 is several times slower.
    idx -= np.array([idx[:, axis].min() for axis in range(3)])
    span = np.array([idx[:, axis].max() for axis in range(3)]) + 1
    keys = (idx[:, 0] * span[1] + idx[:, 1]) * span[2] + idx[:, 2]
    _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    m = len(counts)
    centroids = np.empty((m, 3), dtype=np.float32)
    for axis in range(3):
        centroids[:, axis] = np.bincount(inverse, weights=pts[:, axis], minlength=m) / counts
    return VoxelGrid(size, centroids, counts, inverse)
