"""Depth as a decimated point cloud in ``sensor_msgs/PointCloud2`` layout (no ROS).

Every ``stride``-th pixel of the depth image is back-projected
(:func:`raspv_perception.point_cloud.organised_cloud`), transformed into the published frame
and packed as x, y, z float32 (+ rgb, the PCL/RViz packing of 0x00RRGGBB in a float32) when a
colour image of the same size is given. A 640×480 frame at stride 8 is ≤ 4800 points, 77 KB.
"""
from __future__ import annotations

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.point_cloud import organised_cloud
from raspv_viz.shapes import transform_points

FLOAT32 = 7  # sensor_msgs/PointField.FLOAT32
XYZ = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
XYZRGB = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rgb", "<f4")])


def decimated_points(depth: np.ndarray, intrinsics: CameraIntrinsics, stride: int, max_depth: float,
                     T: np.ndarray, rgb: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Valid points (N, 3) float32 of every ``stride``-th depth pixel within ``max_depth`` [m],
    through ``T`` (· ← C); their colours (N, 3) uint8 when ``rgb`` (H, W, 3) matches the depth."""
    cloud = organised_cloud(depth, intrinsics, stride=stride, min_depth=0.05, max_depth=max_depth)
    points = transform_points(T, cloud.points[cloud.valid]).astype(np.float32)
    colors = None
    if rgb is not None and rgb.shape[:2] == depth.shape[:2]:
        colors = np.ascontiguousarray(rgb[::stride, ::stride][cloud.valid], dtype=np.uint8)
    return points, colors


def pack_cloud(points: np.ndarray, colors: np.ndarray | None = None) -> tuple[list[tuple[str, int]], int, bytes]:
    """(fields as (name, byte offset), point_step, data) of an unorganised little-endian
    PointCloud2 (height 1, width N, all fields FLOAT32)."""
    dtype = XYZ if colors is None else XYZRGB
    out = np.empty(len(points), dtype=dtype)
    out["x"], out["y"], out["z"] = points[:, 0], points[:, 1], points[:, 2]
    if colors is not None:
        c = colors.astype(np.uint32)
        out["rgb"] = ((c[:, 0] << 16) | (c[:, 1] << 8) | c[:, 2]).view(np.float32)
    fields = [(name, dtype.fields[name][1]) for name in dtype.names]
    return fields, dtype.itemsize, out.tobytes()


def unpack_cloud(data: bytes, field_names: list[str]) -> tuple[np.ndarray, np.ndarray | None]:
    """Inverse of :func:`pack_cloud`: points (N, 3) and colours (N, 3) uint8 or None."""
    dtype = XYZRGB if "rgb" in field_names else XYZ
    arr = np.frombuffer(data, dtype=dtype)
    points = np.column_stack([arr["x"], arr["y"], arr["z"]])
    if "rgb" not in field_names:
        return points, None
    c = arr["rgb"].view(np.uint32)
    return points, np.column_stack([(c >> 16) & 255, (c >> 8) & 255, c & 255]).astype(np.uint8)
