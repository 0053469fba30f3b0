"""The camera drivers by name, and device discovery across every installed SDK (no ROS).

Each driver module imports its SDK only when used, so listing the drivers, validating a graph
file or asking for ``--help`` never loads an SDK.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass

from raspv_camera.camera_driver import CameraDriver, CameraSettings
from raspv_camera.rgbd_frame import CameraError, DeviceInfo

DRIVERS: dict[str, str] = {
    "realsense": "raspv_camera.realsense_driver:RealSenseDriver",
    "openni2": "raspv_camera.openni2_driver:OpenNI2Driver",
    "depthai": "raspv_camera.depthai_driver:DepthAIDriver",
}
RECORDING_SUFFIXES = {".db3": "realsense", ".bag": "realsense", ".oni": "openni2", ".mcap": "depthai"}


def driver_class(name: str) -> type[CameraDriver]:
    if name not in DRIVERS:
        raise CameraError(f"unknown camera driver {name!r}; available: {', '.join(DRIVERS)}")
    module, cls = DRIVERS[name].split(":")
    return getattr(importlib.import_module(module), cls)


def make_driver(name: str, settings: CameraSettings) -> CameraDriver:
    """A driver instance (raises ``SdkMissing`` when its SDK is not installed)."""
    return driver_class(name)(settings)


def driver_for_file(path: str) -> str | None:
    """The driver that plays a recording, from its suffix (a directory: DepthAI's .mcap files)."""
    from pathlib import Path

    p = Path(path)
    if p.is_dir() and any(p.glob("*.mcap")):
        return "depthai"
    return RECORDING_SUFFIXES.get(p.suffix.lower())


@dataclass
class SdkDevices:
    """What one SDK found: its ``devices``, or ``error`` (one line) when it cannot look."""

    sdk: str
    devices: list[DeviceInfo]
    error: str = ""


def _devices_of(name: str) -> SdkDevices:
    try:
        return SdkDevices(name, driver_class(name).list_devices())
    except CameraError as exc:
        return SdkDevices(name, [], str(exc))
    except Exception as exc:               # an SDK failing in discovery must not hide the others
        return SdkDevices(name, [], f"{name} device discovery failed: {exc}")


def list_all_devices(names: list[str] | None = None) -> list[SdkDevices]:
    """Connected devices of every (or the named) SDK, searched concurrently (DepthAI's search
    alone takes ≈0.5 s); a missing SDK is reported, not raised."""
    from concurrent.futures import ThreadPoolExecutor

    names = list(names or DRIVERS)
    with ThreadPoolExecutor(max_workers=len(names)) as pool:
        return list(pool.map(_devices_of, names))


def check_recording(path: str, params: dict) -> None:
    """Launch-time check of the camera node's ``file`` (the graph's ``driver`` parameter, or
    the SDK the suffix names): raises ValueError with one line when it cannot be played — a
    missing file, another SDK's suffix, or a file whose structure does not open
    (:mod:`raspv_camera.recording_check`: what ``raspv bag info`` reads of a bag). Loads no SDK."""
    from raspv_camera.recording_check import check_recording_opens

    name = params.get("driver", "auto")
    if name == "auto":
        name = driver_for_file(str(__import__("pathlib").Path(path).expanduser()))
        if name is None:
            raise ValueError(f"{path}: cannot tell which SDK recorded it (.db3/.bag RealSense, .oni OpenNI2, "
                             "a directory of .mcap DepthAI); set 'driver'")
    try:
        checked = driver_class(name)(CameraSettings(file=path)).check_file()
        check_recording_opens(checked, name)
    except CameraError as exc:
        raise ValueError(str(exc)) from None
