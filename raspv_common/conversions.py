"""ROS messages ↔ numpy, written once and used by every node (no rclpy import).

- ``sensor_msgs/Image`` → ndarray is a zero-copy view of the message buffer (read-only);
  ndarray → ``Image`` copies once into the message.
- ``sensor_msgs/CameraInfo`` ↔ :class:`CameraIntrinsics`.
- ``geometry_msgs/Pose`` ↔ 4×4 homogeneous matrix (parent ← child).
- ``builtin_interfaces/Time`` ↔ float seconds.
"""
from __future__ import annotations

import array
import math

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Pose, Quaternion
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header

from raspv_common.intrinsics import OPENCV_DISTORTION_COUNTS, CameraIntrinsics
from raspv_common.rotations import matrix_to_quaternion, quaternion_to_matrix  # noqa: F401 (re-exported)

# encoding → (numpy dtype, channels)
IMAGE_ENCODINGS: dict[str, tuple[np.dtype, int]] = {
    "rgb8": (np.dtype(np.uint8), 3),
    "bgr8": (np.dtype(np.uint8), 3),
    "rgba8": (np.dtype(np.uint8), 4),
    "bgra8": (np.dtype(np.uint8), 4),
    "mono8": (np.dtype(np.uint8), 1),
    "8UC1": (np.dtype(np.uint8), 1),
    "8UC3": (np.dtype(np.uint8), 3),
    "mono16": (np.dtype(np.uint16), 1),
    "16UC1": (np.dtype(np.uint16), 1),
    "32FC1": (np.dtype(np.float32), 1),
}


class ImageEncodingError(ValueError):
    """An Image message that cannot be read as the array it claims to be."""


def image_to_array(msg: Image) -> np.ndarray:
    """``sensor_msgs/Image`` → read-only view (H, W) or (H, W, C) of the message buffer, no copy.

    Raises :class:`ImageEncodingError` for unknown encodings, inconsistent sizes or steps.
    """
    enc = msg.encoding
    if enc not in IMAGE_ENCODINGS:
        raise ImageEncodingError(f"unsupported image encoding {enc!r}; supported: {', '.join(IMAGE_ENCODINGS)}")
    dtype, channels = IMAGE_ENCODINGS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    row = w * channels * dtype.itemsize
    if h == 0 or w == 0:
        raise ImageEncodingError(f"empty {enc} image ({w}x{h})")
    if step < row:
        raise ImageEncodingError(f"{enc} image {w}x{h}: step {step} is smaller than a row ({row} bytes)")
    flat = np.frombuffer(msg.data, dtype=np.uint8)
    if flat.size < step * h:
        raise ImageEncodingError(f"{enc} image {w}x{h}: {flat.size} data bytes, expected {step * h}")
    rows = flat[: step * h].reshape(h, step)[:, :row]
    out = rows.view(dtype.newbyteorder(">" if msg.is_bigendian else "<"))
    if msg.is_bigendian and dtype.itemsize > 1:
        out = out.astype(dtype)  # byte-swapping needs a copy
    out.flags.writeable = False
    return out.reshape(h, w, channels) if channels > 1 else out.reshape(h, w)


def rgb_from_image(msg: Image) -> np.ndarray:
    """Colour image message → RGB uint8 (H, W, 3) (a view for rgb8, a converted copy otherwise)."""
    arr = image_to_array(msg)
    enc = msg.encoding
    if enc in ("rgb8", "8UC3"):
        return arr
    if enc == "bgr8":
        return arr[..., ::-1]
    if enc == "rgba8":
        return arr[..., :3]
    if enc == "bgra8":
        return arr[..., 2::-1]
    if enc in ("mono8", "8UC1"):
        return np.repeat(arr[..., None], 3, axis=2)
    raise ImageEncodingError(f"expected a colour image (rgb8, bgr8, rgba8, bgra8, mono8), got {enc!r}")


def depth_from_image(msg: Image) -> np.ndarray:
    """Depth image message (REP 118: ``32FC1`` metres or ``16UC1``/``mono16`` millimetres) →
    float32 metres (H, W) with NaN where there is no reading (0, NaN, inf, negative)."""
    arr = image_to_array(msg)
    if msg.encoding == "32FC1":
        depth = np.array(arr, dtype=np.float32, copy=True)
        depth[~np.isfinite(depth) | (depth <= 0)] = np.nan
        return depth
    if msg.encoding in ("16UC1", "mono16"):
        depth = arr.astype(np.float32) * np.float32(0.001)
        depth[arr == 0] = np.nan
        return depth
    raise ImageEncodingError(f"expected a depth image (32FC1 metres or 16UC1 millimetres), got {msg.encoding!r}")


def array_to_image(arr: np.ndarray, encoding: str, header: Header | None = None) -> Image:
    """ndarray → ``sensor_msgs/Image`` (one copy into the message buffer)."""
    if encoding not in IMAGE_ENCODINGS:
        raise ImageEncodingError(f"unsupported image encoding {encoding!r}")
    dtype, channels = IMAGE_ENCODINGS[encoding]
    arr = np.ascontiguousarray(arr, dtype=dtype)
    if channels == 1 and arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if (channels == 1 and arr.ndim != 2) or (channels > 1 and (arr.ndim != 3 or arr.shape[2] != channels)):
        raise ImageEncodingError(f"{encoding} needs shape (H, W{'' if channels == 1 else f', {channels}'}), got {arr.shape}")
    msg = Image()
    if header is not None:
        msg.header = header
    msg.height, msg.width = int(arr.shape[0]), int(arr.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = int(arr.shape[1] * channels * dtype.itemsize)
    data = array.array("B")
    data.frombytes(memoryview(arr).cast("B"))    # one copy (arr.tobytes() then array() made two)
    msg.data = data
    return msg


def camera_info_to_intrinsics(msg: CameraInfo) -> CameraIntrinsics:
    """``CameraInfo`` → :class:`CameraIntrinsics` (uses K; raises ``ValueError`` if unset)."""
    k = np.asarray(msg.k, dtype=float)
    if k.size != 9 or k[0] <= 0 or k[4] <= 0 or msg.width == 0 or msg.height == 0:
        raise ValueError(f"camera info has no valid calibration (size {msg.width}x{msg.height}, K={list(k)})")
    return CameraIntrinsics.from_matrix(k.reshape(3, 3), msg.width, msg.height)


# Distortion models whose coefficients are OpenCV's (k1 k2 p1 p2 [k3 [k4 k5 k6]]), as ROS names them.
OPENCV_DISTORTION_MODELS = ("plumb_bob", "rational_polynomial")


def camera_info_distortion(msg: CameraInfo) -> tuple[float, ...]:
    """The lens distortion of a ``CameraInfo`` as OpenCV coefficients (k1 k2 p1 p2 [k3 …]); ``()``
    for a rectified (all-zero or empty) one. Raises ``ValueError`` for a model OpenCV's pinhole
    functions do not take (e.g. ``equidistant``) or a coefficient count they do not know."""
    d = tuple(float(v) for v in msg.d)
    if not any(d):
        return ()
    if msg.distortion_model not in OPENCV_DISTORTION_MODELS:
        raise ValueError(f"distortion model {msg.distortion_model!r} is not supported "
                         f"(only {', '.join(OPENCV_DISTORTION_MODELS)}): rectify the images first")
    if len(d) not in OPENCV_DISTORTION_COUNTS:
        raise ValueError(f"{msg.distortion_model} needs 4, 5 or 8 coefficients, got {len(d)}")
    return d


def intrinsics_to_camera_info(intr: CameraIntrinsics, header: Header | None = None,
                              distortion: tuple[float, ...] = ()) -> CameraInfo:
    """:class:`CameraIntrinsics` → ``CameraInfo`` (plumb_bob model; ``distortion`` k1 k2 p1 p2
    [k3] of the raw images, zero by default; 8 coefficients: rational_polynomial)."""
    msg = CameraInfo()
    if header is not None:
        msg.header = header
    msg.width, msg.height = int(intr.width), int(intr.height)
    d = [float(v) for v in distortion] + [0.0] * (5 - len(distortion))
    msg.distortion_model = "rational_polynomial" if len(d) == 8 else "plumb_bob"
    msg.d = d
    msg.k = [intr.fx, 0.0, intr.cx, 0.0, intr.fy, intr.cy, 0.0, 0.0, 1.0]
    msg.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    msg.p = [intr.fx, 0.0, intr.cx, 0.0, 0.0, intr.fy, intr.cy, 0.0, 0.0, 0.0, 1.0, 0.0]
    return msg


def _rigid(q, p) -> np.ndarray:
    """4×4 from a quaternion message (x, y, z, w) and a point or vector message."""
    T = np.eye(4)
    T[:3, :3] = quaternion_to_matrix(q.x, q.y, q.z, q.w)
    T[:3, 3] = (p.x, p.y, p.z)
    return T


def pose_to_matrix(pose: Pose) -> np.ndarray:
    """``geometry_msgs/Pose`` (child expressed in parent) → 4×4 matrix parent ← child."""
    return _rigid(pose.orientation, pose.position)


def transform_to_matrix(t) -> np.ndarray:
    """``geometry_msgs/Transform`` → 4×4 matrix parent ← child."""
    return _rigid(t.rotation, t.translation)


def matrix_to_pose(T: np.ndarray) -> Pose:
    """4×4 matrix parent ← child → ``geometry_msgs/Pose``."""
    T = np.asarray(T, dtype=float)
    x, y, z, w = matrix_to_quaternion(T[:3, :3])
    return Pose(position=array_to_point(T[:3, 3]), orientation=Quaternion(x=x, y=y, z=z, w=w))


def array_to_point(p) -> Point:
    """(3,) array-like → ``geometry_msgs/Point``."""
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def xyz_to_array(p) -> np.ndarray:
    """Any message with x, y, z (Point, Vector3) → (3,) float64 array."""
    return np.array([p.x, p.y, p.z], dtype=np.float64)


def stamp_to_seconds(stamp: Time) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def seconds_to_stamp(t: float) -> Time:
    sec = math.floor(t)
    nsec = int(round((t - sec) * 1e9))
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return Time(sec=int(sec), nanosec=nsec)
