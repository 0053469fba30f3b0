"""The interface every camera driver implements (no ROS): open a device or a recording, read
registered RGB-D frames and IMU samples, close. One subclass per SDK; the `camera` node and
``raspv camera`` use only this interface.

A driver never sleeps to pace a recording and never retries: it reads as fast as asked and
raises :class:`~raspv_camera.rgbd_frame.NoDevice`, :class:`~raspv_camera.rgbd_frame.DeviceLost`
or :class:`~raspv_camera.rgbd_frame.EndOfRecording`; pacing, stamping and reconnection are the
job of :class:`~raspv_camera.camera_runner.CameraRunner`.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

from raspv_camera.rgbd_frame import DeviceInfo, ImuSample, NoDevice, RgbdFrame


@dataclass(frozen=True)
class CameraSettings:
    """What to open and how: ``device`` (serial number, URI or MxId; empty: the first found),
    ``file`` (a recording to play instead of a device), ``width`` × ``height`` [px] and ``fps``
    [Hz] asked of a live device (a recording plays at its own), ``imu`` (enable the IMU when
    the device has one), ``search_timeout`` [s] (how long to look for a device, where the SDK
    takes one)."""

    device: str = ""
    file: str = ""
    width: int = 640
    height: int = 480
    fps: float = 30.0
    imu: bool = True
    search_timeout: float = 2.0


class CameraDriver(ABC):
    """One SDK's RGB-D source. ``open()`` → ``read()``… → ``close()``; ``imu_samples()`` drains
    the IMU readings that came with the frames read so far."""

    sdk: ClassVar[str]                 # driver name: realsense, openni2, depthai
    file_suffixes: ClassVar[tuple[str, ...]] = ()   # recordings it plays

    def __init__(self, settings: CameraSettings) -> None:
        self.settings = settings
        self.device: DeviceInfo | None = None
        self.has_imu = False
        self.frame_ms = 0.0      # the driver's own work on the last frame returned (pairing, registration, copies) [ms]
        self._imu: list[ImuSample] = []

    @property
    def is_file(self) -> bool:
        return bool(self.settings.file)

    def check_file(self) -> Path:
        """The recording's path, or :class:`NoDevice` saying why it cannot be played."""
        path = Path(self.settings.file).expanduser()
        if not path.exists():
            raise NoDevice(f"{path}: no such recording")
        if self.file_suffixes and path.is_file() and path.suffix.lower() not in self.file_suffixes:
            raise NoDevice(f"{path}: not a {self.sdk} recording (expected {', '.join(self.file_suffixes)})")
        return path

    @abstractmethod
    def open(self) -> DeviceInfo:
        """Open the device or recording and start streaming. Raises ``SdkMissing``,
        ``NoDevice`` or ``CameraError`` (one line each)."""

    @abstractmethod
    def read(self, timeout_s: float) -> RgbdFrame | None:
        """The next registered frame, or None when none came within ``timeout_s``. Raises
        ``DeviceLost`` when the device failed and ``EndOfRecording`` at the end of a file."""

    @abstractmethod
    def close(self) -> None:
        """Stop streaming and release the device (safe to call twice or after a failure)."""

    def imu_samples(self) -> list[ImuSample]:
        """IMU readings received since the last call, oldest first (C frame, see ImuSample)."""
        out, self._imu = self._imu, []
        return out

    @classmethod
    @abstractmethod
    def list_devices(cls) -> list[DeviceInfo]:
        """Connected devices (fast; an empty list when none)."""

    @classmethod
    @abstractmethod
    def describe(cls, settings: CameraSettings) -> list[str]:
        """Lines describing a device's (or recording's) modes and intrinsics."""

    def __enter__(self) -> "CameraDriver":
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()
