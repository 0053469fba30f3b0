"""What a camera driver hands the node (no ROS): RGB-D frames, IMU samples, device
descriptions, and the errors a driver raises.

Frames: the colour camera's optical frame C (x right, y down, z forward); depth is registered
to colour by the SDK, so one :class:`CameraIntrinsics` describes both images.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics


class CameraError(Exception):
    """A camera problem reported as one line (no traceback): ``str(exc)`` says what and what to do."""


class SdkMissing(CameraError):
    """The vendor SDK or a system library it needs is not installed (the message names the
    ``pip install`` or ``apt-get install`` that fixes it)."""


class NoDevice(CameraError):
    """No device (or not the one asked for) is connected, or a recording file cannot be opened."""


class DeviceLost(CameraError):
    """An open device stopped delivering (unplugged, USB error, firmware crash)."""


@dataclass
class RgbdFrame:
    """One registered RGB-D frame.

    ``color`` (H, W, 3) uint8 RGB; ``depth`` (H, W) uint16 in ``depth_units`` metres per unit
    (0 = no reading), registered to colour; ``intrinsics`` of the colour camera (and so of the
    registered depth); ``sensor_time`` the device's own timestamp of the frame [s] on the
    device clock (or the recording's); ``frame_number`` the device's counter; ``distortion`` the
    colour lens's OpenCV coefficients (k1 k2 p1 p2 k3 [k4 k5 k6], :mod:`raspv_camera.lens_distortion`),
    ``()`` for rectified images.
    """

    color: np.ndarray
    depth: np.ndarray
    depth_units: float
    intrinsics: CameraIntrinsics
    sensor_time: float
    frame_number: int = 0
    distortion: tuple[float, ...] = ()

    def depth_metres(self) -> np.ndarray:
        """Depth as float32 metres with NaN where there is no reading."""
        out = self.depth.astype(np.float32) * np.float32(self.depth_units)
        out[self.depth == 0] = np.nan
        return out


@dataclass
class ImuSample:
    """One accelerometer (and gyroscope, when the device has one) reading in the colour
    camera's optical frame C: ``accel`` [m/s²] (specific force: at rest it points up, away from
    the floor), ``gyro`` [rad/s] or None; ``sensor_time`` [s] on the device clock."""

    sensor_time: float
    accel: np.ndarray
    gyro: np.ndarray | None = None


@dataclass
class StreamMode:
    """A mode a device offers: ``stream`` (``color``, ``depth``, ``accel``, ``gyro`` …),
    ``width`` × ``height`` [px] (0 for motion streams), ``fps`` [Hz] and the SDK's format name."""

    stream: str
    width: int
    height: int
    fps: float
    format: str

    def __str__(self) -> str:
        size = f"{self.width}x{self.height} " if self.width else ""
        return f"{self.stream:6s} {size}{self.format} @ {self.fps:g} Hz"


@dataclass
class DeviceInfo:
    """A device an SDK can open: ``sdk`` (driver name), ``id`` (serial number, URI or MxId: what
    the ``device`` parameter takes), ``name`` (model), and free-form ``details`` (firmware,
    USB port, state)."""

    sdk: str
    id: str
    name: str
    details: dict[str, str] = field(default_factory=dict)

    def line(self) -> str:
        extra = ", ".join(f"{k} {v}" for k, v in self.details.items())
        return f"{self.sdk:9s} {self.id:24s} {self.name}" + (f"  ({extra})" if extra else "")


class EndOfRecording(CameraError):
    """A recording played to its end."""
