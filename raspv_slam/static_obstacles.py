"""What stayed put: obstacle points of a map that the keyframes' own depth contradicts (no ROS).

A person walking through a mapped corridor leaves a trail of points in the keyframes that saw
them, and a floor-projected occupancy grid draws that trail as walls. Free-space evidence
removes it, as visibility-based map cleaning does (Kim & Kim, "Remove, then Revert", IROS 2020;
OctoMap's ray-carved misses): the obstacle points are gathered in voxels, and every voxel is
projected into every keyframe's depth image. A keyframe

- *sees through* the voxel when the depth it measured around that pixel (all of a 3×3
  neighbourhood, so edges and grazing walls do not count) lies farther than the voxel by more
  than the tolerance: at that moment the space was empty;
- *sees* it when the depth at the pixel agrees with the voxel's within the tolerance;
- says nothing when the voxel is hidden behind something nearer, out of view or out of range,
  or the depth has a hole there.

A voxel is static when it was not seen through by more keyframes than saw it: a wall is seen by
every keyframe that looks at it, a walker's place is seen while they stand there and through
once they have gone. Tolerance: the voxel's half diagonal plus ``tolerance`` + ``tolerance_z2``
· z² (structured-light noise grows with z², Khoshelham & Elberink 2012, plus pose error).

Frames: points and ``map_from_camera`` in the map frame M (metres); cameras are optical frames
(x right, y down, z forward) of ``intrinsics``, the size of the depth images.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics

VOXEL = 0.05                # m: the occupancy grid's cell
TOLERANCE = 0.05            # m beyond the voxel's half diagonal: pose error of a loop-closed map
TOLERANCE_Z2 = 0.006        # m per m²: ≈ 2σ of a Kinect-class sensor's depth noise (σ ≈ 2.9 mm·z²)
_NEIGHBOURHOOD = np.ones((3, 3), np.uint8)


@dataclass(frozen=True)
class DepthView:
    """One keyframe: ``map_from_camera`` M ← C (4×4) and its depth image (H, W) [m], NaN = none."""

    map_from_camera: np.ndarray
    depth: np.ndarray


@dataclass(frozen=True)
class Evidence:
    """Per point: how many views saw its voxel (``seen``) and saw through it (``through``)."""

    seen: np.ndarray
    through: np.ndarray

    @property
    def static(self) -> np.ndarray:
        return self.through <= self.seen


def visibility_evidence(points: np.ndarray, views: list[DepthView], intrinsics: CameraIntrinsics,
                        max_depth: float, voxel: float = VOXEL, tolerance: float = TOLERANCE,
                        tolerance_z2: float = TOLERANCE_Z2) -> Evidence:
    """Count, for the voxel of every point (N, 3) in M, the views that saw it and saw through it.

    Only voxels nearer than ``max_depth`` to a camera are judged by it (farther, the depth is too
    noisy to say either)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not len(points):
        return Evidence(np.zeros(0, np.int32), np.zeros(0, np.int32))
    cells = np.floor(points / voxel).astype(np.int64)
    cells -= cells.min(axis=0)
    span = cells.max(axis=0) + 1
    keys = (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]
    _, inverse = np.unique(keys, return_inverse=True)
    inverse = inverse.reshape(-1)
    n_voxels = int(inverse.max()) + 1
    counts = np.bincount(inverse, minlength=n_voxels)
    # the mean point of each voxel: on the surface, not the cube's centre
    centres = np.stack([np.bincount(inverse, points[:, i], n_voxels) for i in range(3)], axis=1) / counts[:, None]
    centres = centres.astype(np.float32)
    seen = np.zeros(n_voxels, np.int32)
    through = np.zeros(n_voxels, np.int32)
    for view in views:
        judge_view(centres, view, intrinsics, max_depth, seen, through, voxel, tolerance, tolerance_z2)
    return Evidence(seen[inverse], through[inverse])


def judge_view(centres: np.ndarray, view: DepthView, intrinsics: CameraIntrinsics, max_depth: float,
               seen: np.ndarray, through: np.ndarray, voxel: float = VOXEL, tolerance: float = TOLERANCE,
               tolerance_z2: float = TOLERANCE_Z2, candidates: np.ndarray | None = None) -> None:
    """Add one view's votes to ``seen`` and ``through`` (in place) for the voxel ``centres``
    (V, 3) float32 in M; ``candidates``: indices of the centres that may be in reach (all when None)."""
    K = intrinsics
    depth = np.asarray(view.depth, dtype=np.float32)
    if depth.shape != (K.height, K.width):
        raise ValueError(f"a depth view is {depth.shape[1]}x{depth.shape[0]}, the intrinsics {K.width}x{K.height}")
    subset = centres if candidates is None else centres[candidates]
    R = view.map_from_camera[:3, :3].astype(np.float32)
    p = (subset - view.map_from_camera[:3, 3].astype(np.float32)) @ R       # camera frame: R^T (x - t)
    z = p[:, 2]
    ok = (z > 1e-3) & (z <= max_depth)
    idx = np.flatnonzero(ok)
    if not len(idx):
        return
    u = np.rint(K.fx * p[idx, 0] / z[idx] + K.cx).astype(np.int64)
    v = np.rint(K.fy * p[idx, 1] / z[idx] + K.cy).astype(np.int64)
    inside = (u >= 1) & (u < K.width - 1) & (v >= 1) & (v < K.height - 1)
    idx, u, v = idx[inside], u[inside], v[inside]
    measured = depth[v, u]
    nearest_around = cv2.erode(np.nan_to_num(depth, nan=0.0), _NEIGHBOURHOOD, borderType=cv2.BORDER_REPLICATE)[v, u]
    zi = z[idx]
    tol = voxel * np.sqrt(3.0) / 2.0 + tolerance + tolerance_z2 * zi * zi
    target = idx if candidates is None else candidates[idx]
    seen[target[np.abs(measured - zi) <= tol]] += 1
    through[target[nearest_around > zi + tol]] += 1


def reach(intrinsics: CameraIntrinsics, max_depth: float) -> float:
    """[m] the farthest a point with optical depth <= ``max_depth`` inside the image can be from
    the camera (the image corner's ray): voxels farther away get no vote from it."""
    K = intrinsics
    corner = max(abs(0 - K.cx), abs(K.width - 1 - K.cx)) / K.fx, max(abs(0 - K.cy), abs(K.height - 1 - K.cy)) / K.fy
    return float(max_depth * np.sqrt(1.0 + corner[0] ** 2 + corner[1] ** 2))
