"""OpenNI2 devices (PrimeSense Carmine, Asus Xtion — the paper's camera —, Kinect with its driver)
through Debian's libOpenNI2 and the ``openni`` bindings (no ROS): live devices by URI (``Dummy``
opens the library's synthetic device), or an ``.oni`` recording.

Depth is registered to colour by the device (``IMAGE_REGISTRATION_DEPTH_TO_COLOR``) and frames
are synchronised by it where it can; a recording holds whatever the recording device sent.
Colour and depth are read from both streams (OpenNI2 stalls a stream that is not read) and
paired by timestamp (within half a frame period). Intrinsics come from the colour stream's
field of view; devices and files that do not report one (the dummy device) get the PrimeSense
default f = 525 px at 640 px width. A recording is played in manual-speed mode
(``set_speed(-1.0)``: a frame per read) and paced by the runner.
"""
from __future__ import annotations

import ctypes
import math
import time

import numpy as np

from raspv_camera import sdk_imports
from raspv_camera.camera_driver import CameraDriver, CameraSettings
from raspv_camera.rgbd_frame import (CameraError, DeviceInfo, DeviceLost, EndOfRecording, NoDevice, RgbdFrame)
from raspv_common.intrinsics import CameraIntrinsics

PRIMESENSE_F_AT_640 = 525.0      # px, PrimeSense/Kinect default focal length at 640 px width
_DEPTH_UNITS = {"ONI_PIXEL_FORMAT_DEPTH_1_MM": 0.001, "ONI_PIXEL_FORMAT_DEPTH_100_UM": 0.0001}


def _fmt(mode) -> str:
    return repr(mode.pixelFormat).split(".")[-1]


def _device_list(ni) -> list[tuple[str, str, str]]:
    """(uri, vendor, name) of the connected devices (the library also lists, once per opening,
    the recordings and the synthetic ``Dummy`` device this process opened: they are left out)."""
    from openni import _openni2 as c_api

    pdevs = ctypes.POINTER(c_api.OniDeviceInfo)()
    count = ctypes.c_int()
    c_api.oniGetDeviceList(ctypes.byref(pdevs), ctypes.byref(count))
    out = [(pdevs[i].uri.decode(errors="replace"), pdevs[i].vendor.decode(errors="replace"),
            pdevs[i].name.decode(errors="replace")) for i in range(count.value)]
    c_api.oniReleaseDeviceList(pdevs)
    unique = {}
    for uri, vendor, name in out:
        if uri != "Dummy" and not uri.lower().endswith(".oni"):
            unique.setdefault(uri, (uri, vendor, name))
    return list(unique.values())


def stream_intrinsics(stream, width: int, height: int) -> tuple[CameraIntrinsics, bool]:
    """Intrinsics of a stream from its field of view, and whether they came from the device
    (False: the PrimeSense default focal length, scaled to ``width``)."""
    try:
        hfov = float(stream.get_horizontal_fov())
        vfov = float(stream.get_vertical_fov())
        if 0.1 < hfov < math.pi and 0.1 < vfov < math.pi:
            return CameraIntrinsics(width, height, width / (2 * math.tan(hfov / 2)), height / (2 * math.tan(vfov / 2)),
                                    (width - 1) / 2, (height - 1) / 2), True
    except Exception:       # the bindings raise OpenNIError(NOT_IMPLEMENTED) when there is no FOV property
        pass
    f = PRIMESENSE_F_AT_640 * width / 640.0
    return CameraIntrinsics(width, height, f, f, (width - 1) / 2, (height - 1) / 2), False


class OpenNI2Driver(CameraDriver):
    sdk = "openni2"
    file_suffixes = (".oni",)

    def __init__(self, settings: CameraSettings) -> None:
        super().__init__(settings)
        self.ni = sdk_imports.openni2()
        self.dev = None
        self.streams: list = []
        self.intrinsics: CameraIntrinsics | None = None
        self.intrinsics_from_device = False
        self.registered = False
        self.depth_units = 0.001
        self.frame_period = 1 / 30
        self._pending: list[list[tuple[float, int, np.ndarray]]] = [[], []]   # depth, colour: (t, index, data)
        self._counts = [0, 0]
        self._totals = [0, 0]
        self._work_s = 0.0

    # -- open ----------------------------------------------------------------------------------
    def open(self) -> DeviceInfo:
        ni = self.ni
        s = self.settings
        try:
            if self.is_file:
                path = self.check_file()
                self.dev = ni.Device.open_file(str(path).encode())
            else:
                uris = [u for u, _, _ in _device_list(ni)]
                if not s.device and not uris:
                    raise NoDevice("no OpenNI2 device connected (Asus Xtion, PrimeSense, Kinect with its driver)")
                if s.device and s.device != "Dummy" and s.device not in uris:
                    raise NoDevice(f"no OpenNI2 device {s.device} (connected: {', '.join(uris) or 'none'})")
                self.dev = ni.Device((s.device or uris[0]).encode())
        except NoDevice:
            raise
        except Exception as exc:       # OpenNIError from the library
            raise NoDevice(f"cannot open {s.file or s.device or 'the OpenNI2 device'}: {exc}") from None
        try:
            self._start()
        except Exception:
            self.close()
            raise
        info = self.dev.get_device_info()
        name = " ".join(x.decode(errors="replace") for x in (info.vendor, info.name) if x) or "OpenNI2 device"
        self.device = DeviceInfo(self.sdk, s.file or info.uri.decode(errors="replace"), name,
                                 {"registered": "yes" if self.registered else "no"})
        return self.device

    def _start(self) -> None:
        ni = self.ni
        s = self.settings
        dev = self.dev
        if not dev.has_sensor(ni.SENSOR_DEPTH) or not dev.has_sensor(ni.SENSOR_COLOR):
            raise CameraError(f"{s.file or 'the device'} has no {'depth' if not dev.has_sensor(ni.SENSOR_DEPTH) else 'colour'} stream")
        depth, color = dev.create_depth_stream(), dev.create_color_stream()
        if self.is_file:
            dev.playback.set_repeat_enabled(False)
            dev.playback.set_speed(-1.0)     # manual: one frame per read (must be a float)
            self._totals = [dev.playback.get_number_of_frames(depth), dev.playback.get_number_of_frames(color)]
        else:
            for stream, formats in ((depth, ("ONI_PIXEL_FORMAT_DEPTH_1_MM", "ONI_PIXEL_FORMAT_DEPTH_100_UM")),
                                    (color, ("ONI_PIXEL_FORMAT_RGB888",))):
                modes = stream.get_sensor_info().videoModes
                match = [m for m in modes if (m.resolutionX, m.resolutionY, m.fps) == (s.width, s.height, int(round(s.fps)))
                         and _fmt(m) in formats]
                if not match:
                    have = ", ".join(sorted({f"{m.resolutionX}x{m.resolutionY}@{m.fps} {_fmt(m)}" for m in modes}))
                    raise CameraError(f"the OpenNI2 device has no {s.width}x{s.height} @ {s.fps:g} Hz "
                                      f"{'depth' if stream is depth else 'colour'} mode (it has: {have})")
                current = stream.get_video_mode()
                if (current.resolutionX, current.resolutionY, current.fps, _fmt(current)) != (
                        match[0].resolutionX, match[0].resolutionY, match[0].fps, _fmt(match[0])):
                    try:
                        stream.set_video_mode(match[0])
                    except Exception as exc:
                        raise CameraError(f"the OpenNI2 device refused {s.width}x{s.height} @ {s.fps:g} Hz: {exc}") from None
            if dev.is_image_registration_mode_supported(ni.IMAGE_REGISTRATION_DEPTH_TO_COLOR):
                dev.set_image_registration_mode(ni.IMAGE_REGISTRATION_DEPTH_TO_COLOR)
                self.registered = True
            try:
                dev.set_depth_color_sync_enabled(True)
            except Exception:
                pass
        if self.is_file:
            try:
                self.registered = dev.get_image_registration_mode().value == ni.IMAGE_REGISTRATION_DEPTH_TO_COLOR.value
            except Exception:
                self.registered = False
        dmode, cmode = depth.get_video_mode(), color.get_video_mode()
        if _fmt(dmode) not in _DEPTH_UNITS:
            raise CameraError(f"OpenNI2 depth format {_fmt(dmode)} is not supported (DEPTH_1_MM, DEPTH_100_UM)")
        self.depth_units = _DEPTH_UNITS[_fmt(dmode)]
        self.frame_period = 1.0 / max(1, cmode.fps)
        self.intrinsics, self.intrinsics_from_device = stream_intrinsics(color, cmode.resolutionX, cmode.resolutionY)
        depth.start()
        color.start()
        self.streams = [depth, color]
        self._pending = [[], []]
        self._counts = [0, 0]

    # -- read ----------------------------------------------------------------------------------
    def read(self, timeout_s: float) -> RgbdFrame | None:
        ni = self.ni
        if not self.streams:
            raise DeviceLost("the OpenNI2 streams are not running")
        deadline = time.monotonic() + timeout_s
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            try:
                stream = ni.wait_for_any_stream(self.streams, remaining)
                if stream is None:
                    break
                frame = stream.read_frame()
            except Exception as exc:
                raise DeviceLost(f"OpenNI2: {exc}") from None
            t0 = time.perf_counter()
            k = self.streams.index(stream)
            self._counts[k] += 1
            out = self._take(k, frame)
            self._work_s += time.perf_counter() - t0
            if out is not None:
                self.frame_ms, self._work_s = 1e3 * self._work_s, 0.0
                return out
        if self.is_file and all(c >= t for c, t in zip(self._counts, self._totals)):
            raise EndOfRecording(f"{self.settings.file}: end of recording")
        return None

    def _take(self, k: int, frame) -> RgbdFrame | None:
        """Buffer a frame of stream ``k`` (0 depth, 1 colour) and return an RGB-D frame when it
        completes a pair (timestamps within half a frame period). Frames older than a pair
        have lost their partner and are dropped; each stream keeps its last few frames."""
        t = frame.timestamp * 1e-6
        w, h = frame.width, frame.height
        if k == 0:
            data = np.frombuffer(frame.get_buffer_as_uint16(), np.uint16)[: w * h].reshape(h, w).copy()
        else:
            data = self._rgb(frame, w, h)
        mine, other = self._pending[k], self._pending[1 - k]
        partner = min(other, key=lambda e: abs(e[0] - t), default=None)
        if partner is None or abs(partner[0] - t) > 0.5 * self.frame_period:
            mine.append((t, int(frame.frameIndex), data))
            del mine[:-4]
            return None
        other[:] = [e for e in other if e[0] > partner[0]]
        mine[:] = [e for e in mine if e[0] > t]
        (tc, index, color), depth = ((t, int(frame.frameIndex), data), partner[2]) if k == 1 else (partner, data)
        if depth.shape != color.shape[:2]:
            import cv2
            depth = cv2.resize(depth, (color.shape[1], color.shape[0]), interpolation=cv2.INTER_NEAREST)
        K = self.intrinsics
        if (K.width, K.height) != (color.shape[1], color.shape[0]):
            K = K.scaled(color.shape[1], color.shape[0])
        return RgbdFrame(color=color, depth=depth, depth_units=self.depth_units, intrinsics=K, sensor_time=tc,
                         frame_number=index)

    @staticmethod
    def _rgb(frame, w: int, h: int) -> np.ndarray:
        fmt = _fmt(frame.videoMode)
        raw = np.frombuffer(frame.get_buffer_as_uint8(), np.uint8)
        if fmt == "ONI_PIXEL_FORMAT_RGB888":
            return raw[: w * h * 3].reshape(h, w, 3).copy()
        import cv2
        if fmt in ("ONI_PIXEL_FORMAT_YUV422", "ONI_PIXEL_FORMAT_YUYV"):
            code = cv2.COLOR_YUV2RGB_UYVY if fmt == "ONI_PIXEL_FORMAT_YUV422" else cv2.COLOR_YUV2RGB_YUYV
            return cv2.cvtColor(raw[: w * h * 2].reshape(h, w, 2), code)
        if fmt == "ONI_PIXEL_FORMAT_GRAY8":
            return np.repeat(raw[: w * h].reshape(h, w, 1), 3, axis=2)
        if fmt == "ONI_PIXEL_FORMAT_JPEG":
            bgr = cv2.imdecode(raw[: frame.dataSize], cv2.IMREAD_COLOR)
            if bgr is None:
                raise DeviceLost("OpenNI2: a JPEG colour frame could not be decoded")
            return bgr[..., ::-1].copy()
        raise CameraError(f"OpenNI2 colour format {fmt} is not supported")

    def close(self) -> None:
        for stream in self.streams:
            try:
                stream.stop()
            except Exception:
                pass
        if self.streams:
            time.sleep(0.2)        # the dummy driver may crash when closed right after its streams stop
        self.streams = []
        if self.dev is not None:
            try:
                self.dev.close()
            except Exception:
                pass
            self.dev = None

    # -- discovery -----------------------------------------------------------------------------
    @classmethod
    def list_devices(cls) -> list[DeviceInfo]:
        ni = sdk_imports.openni2()
        return [DeviceInfo(cls.sdk, uri, f"{vendor} {name}".strip()) for uri, vendor, name in _device_list(ni)]

    @classmethod
    def describe(cls, settings: CameraSettings) -> list[str]:
        ni = sdk_imports.openni2()
        if settings.file:
            driver = cls(settings)
            driver.open()
            try:
                d, c = (s.get_video_mode() for s in driver.streams)
                return [f"{driver.device.name}: {settings.file}",
                        f"  depth  {d.resolutionX}x{d.resolutionY} {_fmt(d)} @ {d.fps} Hz, {driver._totals[0]} frames",
                        f"  colour {c.resolutionX}x{c.resolutionY} {_fmt(c)} @ {c.fps} Hz, {driver._totals[1]} frames",
                        f"  intrinsics {_intrinsics_line(driver.intrinsics, driver.intrinsics_from_device)}",
                        f"  depth registered to colour: {'yes' if driver.registered else 'unknown/no'}"]
            finally:
                driver.close()
        uris = [u for u, _, _ in _device_list(ni)]
        uri = settings.device or (uris[0] if uris else "")
        if not uri:
            raise NoDevice("no OpenNI2 device connected")
        try:
            dev = ni.Device(uri.encode())
        except Exception as exc:
            raise NoDevice(f"cannot open OpenNI2 device {uri}: {exc}") from None
        try:
            info = dev.get_device_info()
            lines = [f"{info.vendor.decode()} {info.name.decode()} ({uri})"]
            for kind, label in ((ni.SENSOR_COLOR, "colour"), (ni.SENSOR_DEPTH, "depth"), (ni.SENSOR_IR, "ir")):
                if not dev.has_sensor(kind):
                    continue
                stream = dev.create_stream(kind)
                for m in stream.get_sensor_info().videoModes:
                    K, real = stream_intrinsics(stream, m.resolutionX, m.resolutionY)
                    lines.append(f"  {label:6s} {m.resolutionX}x{m.resolutionY} {_fmt(m)} @ {m.fps} Hz  "
                                 f"{_intrinsics_line(K, real)}")
                stream.close()
            lines.append("  depth-to-colour registration: " + (
                "yes" if dev.is_image_registration_mode_supported(ni.IMAGE_REGISTRATION_DEPTH_TO_COLOR) else "no"))
            return lines
        finally:
            dev.close()


def _intrinsics_line(K: CameraIntrinsics, from_device: bool) -> str:
    src = "from the field of view" if from_device else "PrimeSense default, no field of view reported"
    return f"fx {K.fx:.1f} fy {K.fy:.1f} cx {K.cx:.1f} cy {K.cy:.1f} ({src})"
