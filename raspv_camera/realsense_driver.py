"""Intel RealSense through ``pyrealsense2`` (no ROS): live D400/L500 devices by serial number,
or a recording (``.db3`` written by SDK ≥ 2.58, ``.bag`` by older ones).

The driver works at the sensor level, live or recorded alike: the depth, colour and (D435i,
D455) motion sensors are opened on the asked modes (a recording: on what it holds) and deliver
through callbacks; colour and depth are paired by timestamp
(:class:`~raspv_camera.frame_pairing.FramePairer`) and the pair is registered by the SDK
(``rs.align(rs.stream.color)`` on a composite frame set); depth stays in the device's units
(``depth_scale``, usually 1 mm). A recording plays with ``set_real_time(False)`` and its
callbacks block while frames wait to be read, so the SDK hands over every frame of every
stream (``rs.pipeline`` drops frame sets when its reader is slower than the file) and the
runner paces them by their timestamps; playback is paused until every sensor is started, so
none misses the first frames. Live frames never block the SDK: the oldest waiting frame is
dropped instead. Motion samples (every one, at the IMU's rate) are rotated into the colour
optical frame with the device's extrinsics. An unplugged device is noticed through the
context's device-change callback.
"""
from __future__ import annotations

import collections
import queue
import threading
import time

import numpy as np

from raspv_camera import lens_distortion, sdk_imports
from raspv_camera.camera_driver import CameraDriver, CameraSettings
from raspv_camera.frame_pairing import FramePairer, pair_tolerance
from raspv_camera.rgbd_frame import (CameraError, DeviceInfo, DeviceLost, EndOfRecording, ImuSample, NoDevice,
                                     RgbdFrame)
from raspv_common.intrinsics import CameraIntrinsics

VIDEO_QUEUE = 4          # colour/depth frames waiting to be read


def _info(rs, dev, key: str) -> str:
    k = getattr(rs.camera_info, key)
    return dev.get_info(k) if dev.supports(k) else ""


def _intrinsics(profile) -> CameraIntrinsics:
    i = profile.as_video_stream_profile().get_intrinsics()
    return CameraIntrinsics(int(i.width), int(i.height), float(i.fx), float(i.fy), float(i.ppx), float(i.ppy))


def _rotation_to(src, dst) -> np.ndarray:
    """dst ← src rotation (3×3) from the device's extrinsics; identity when not recorded."""
    try:
        e = src.get_extrinsics_to(dst)
    except RuntimeError:
        return np.eye(3)
    R = np.asarray(e.rotation, dtype=np.float64).reshape(3, 3).T    # librealsense stores column-major
    return R if abs(np.linalg.det(R) - 1.0) < 1e-3 else np.eye(3)


class RealSenseDriver(CameraDriver):
    sdk = "realsense"
    file_suffixes = (".db3", ".bag")

    def __init__(self, settings: CameraSettings) -> None:
        super().__init__(settings)
        self.rs = sdk_imports.realsense()
        self.ctx = None
        self.dev = None
        self.playback = None
        self.sensors: list = []
        self.depth_units = 0.001
        self.intrinsics: CameraIntrinsics | None = None
        self.distortion: tuple[float, ...] = ()
        self.profiles: dict = {}
        self._imu_rotation: dict = {}
        self._video: queue.Queue = queue.Queue(maxsize=VIDEO_QUEUE)
        self._motion: collections.deque = collections.deque(maxlen=2000)
        self._pairer: FramePairer | None = None
        self._closing = threading.Event()
        self._unplugged = threading.Event()
        self._work_s = 0.0

    # -- open ----------------------------------------------------------------------------------
    def open(self) -> DeviceInfo:
        rs = self.rs
        self.ctx = rs.context()
        if self.is_file:
            path = self.check_file()
            try:
                self.dev = self.ctx.load_device(str(path))
            except RuntimeError as exc:
                raise NoDevice(f"cannot start {path}: {exc}") from None
            self.playback = self.dev.as_playback()
            self.playback.set_real_time(False)
            self.playback.pause()
            chosen = {sensor: list(sensor.get_stream_profiles()) for sensor in self.dev.query_sensors()}
        else:
            self.dev = self._find_device()
            chosen = self._live_profiles()
            self.ctx.set_devices_changed_callback(self._devices_changed)
        for sensor, profiles in chosen.items():
            for sp in profiles:
                self.profiles.setdefault(sp.stream_type(), sp)
        if rs.stream.color not in self.profiles or rs.stream.depth not in self.profiles:
            missing = "colour" if rs.stream.color not in self.profiles else "depth"
            self.close()
            raise CameraError(f"{self.settings.file or 'the device'} has no {missing} stream")
        color = self.profiles[rs.stream.color]
        self.intrinsics = _intrinsics(color)
        self.distortion = self._distortion(color)
        self.depth_units = float(self.dev.first_depth_sensor().get_depth_scale())
        self._imu_rotation = {k: _rotation_to(self.profiles[k], color) for k in (rs.stream.accel, rs.stream.gyro)
                              if k in self.profiles}
        self.has_imu = rs.stream.accel in self._imu_rotation
        self._pairer = FramePairer(pair_tolerance(color.fps()))
        self.align = rs.align(rs.stream.color)
        self._pair: dict = {}
        self._composed = rs.frame_queue(2, keep_frames=True)
        self._composer = rs.processing_block(self._compose)
        self._composer.start(self._composed)
        try:
            for sensor, profiles in chosen.items():
                sensor.open(profiles)
                self.sensors.append(sensor)
                sensor.start(self._on_frame)
            if self.playback is not None:
                self.playback.resume()
        except RuntimeError as exc:
            self.close()
            raise NoDevice(f"cannot start {self.settings.file or 'the RealSense device'}: {exc}") from None
        name = _info(rs, self.dev, "name") or "RealSense recording"
        ident = self.settings.file or _info(rs, self.dev, "serial_number")
        details = {"firmware": _info(rs, self.dev, "firmware_version"), "usb": _info(rs, self.dev, "usb_type_descriptor")}
        self.device = DeviceInfo(self.sdk, ident, name, {k: v for k, v in details.items() if v})
        return self.device

    def _distortion(self, color) -> tuple[float, ...]:
        """The colour lens's OpenCV coefficients (the depth is aligned to colour); a model with
        none, or a poor fit, is said once on stdout and passed on as rectified/fitted."""
        i = color.as_video_stream_profile().get_intrinsics()
        model = str(i.model).split(".")[-1]

        def project(points):
            return [self.rs.rs2_project_point_to_pixel(i, [float(v) for v in p]) for p in points]
        try:
            coefficients, residual = lens_distortion.from_realsense(model, list(i.coeffs), self.intrinsics, project)
        except lens_distortion.UnsupportedDistortion as exc:
            print(f"realsense: {exc}: publishing the colour camera as rectified", flush=True)
            return ()
        if residual > lens_distortion.FIT_TOLERANCE_PX:
            print(f"realsense: colour lens model {model} fitted as OpenCV's to within {residual:.2f} px only",
                  flush=True)
        return coefficients

    def _find_device(self):
        rs = self.rs
        s = self.settings
        devices = list(self.ctx.query_devices())
        if not devices:
            raise NoDevice("no RealSense device connected")
        serials = [_info(rs, d, "serial_number") for d in devices]
        if s.device and s.device not in serials:
            raise NoDevice(f"no RealSense device with serial number {s.device} (connected: {', '.join(serials)})")
        return devices[serials.index(s.device)] if s.device else devices[0]

    def _live_profiles(self) -> dict:
        """Sensor → the profiles asked: depth z16 and colour rgb8 at width × height @ fps, and
        the accelerometer and gyroscope at their lowest rates."""
        rs = self.rs
        s = self.settings
        want = {rs.stream.depth: rs.format.z16, rs.stream.color: rs.format.rgb8}
        picked: dict = {}
        for sensor in self.dev.query_sensors():
            for sp in sensor.get_stream_profiles():
                kind = sp.stream_type()
                if kind in want and kind not in picked and sp.format() == want[kind] and sp.fps() == int(round(s.fps)):
                    v = sp.as_video_stream_profile()
                    if (v.width(), v.height()) == (s.width, s.height):
                        picked[kind] = (sensor, sp)
                elif s.imu and kind in (rs.stream.accel, rs.stream.gyro):
                    if kind not in picked or sp.fps() < picked[kind][1].fps():
                        picked[kind] = (sensor, sp)
        for kind in want:
            if kind not in picked:
                raise CameraError(f"RealSense {_info(rs, self.dev, 'name')} has no {s.width}x{s.height} @ {s.fps:g} Hz "
                                  f"{'colour' if kind == rs.stream.color else 'depth'} mode; see `raspv camera info realsense`")
        chosen: dict = {}
        for sensor, sp in picked.values():
            chosen.setdefault(sensor, []).append(sp)
        return chosen

    def _devices_changed(self, event) -> None:
        try:
            if event.was_removed(self.dev):
                self._unplugged.set()
        except RuntimeError:
            self._unplugged.set()

    # -- SDK threads ---------------------------------------------------------------------------
    def _on_frame(self, frame) -> None:
        rs = self.rs
        kind = frame.profile.stream_type()
        if kind in (rs.stream.accel, rs.stream.gyro):
            d = frame.as_motion_frame().get_motion_data()
            self._motion.append((kind, frame.get_timestamp() * 1e-3, np.array([d.x, d.y, d.z], dtype=np.float64)))
            return
        if kind not in (rs.stream.color, rs.stream.depth):
            return
        frame.keep()                             # it outlives this callback
        if self.playback is not None:            # a recording waits for the reader: nothing is lost
            while not self._closing.is_set():
                try:
                    self._video.put(frame, timeout=0.1)
                    return
                except queue.Full:
                    continue
            return
        while True:                              # a live device never waits: the oldest goes
            try:
                self._video.put_nowait(frame)
                return
            except queue.Full:
                try:
                    self._video.get_nowait()
                except queue.Empty:
                    pass

    def _compose(self, _frame, source) -> None:
        source.frame_ready(source.allocate_composite_frame([self._pair["depth"], self._pair["color"]]))

    # -- read ----------------------------------------------------------------------------------
    def read(self, timeout_s: float) -> RgbdFrame | None:
        rs = self.rs
        if not self.sensors:
            raise DeviceLost("the RealSense sensors are not running")
        deadline = time.monotonic() + timeout_s
        while True:
            if self._unplugged.is_set():
                raise DeviceLost(f"RealSense {self.device.id} was unplugged")
            self._collect_motion()
            remaining = deadline - time.monotonic()
            try:
                frame = self._video.get(timeout=max(0.0, min(remaining, 0.1)))
            except queue.Empty:
                if self.playback is not None and self._playback_stopped() and self._video.empty():
                    raise EndOfRecording(f"{self.settings.file}: end of recording") from None
                if remaining <= 0:
                    return None
                continue
            t0 = time.perf_counter()
            kind = "color" if frame.profile.stream_type() == rs.stream.color else "depth"
            pair = self._pairer.add(kind, frame.get_timestamp() * 1e-3, frame)
            if pair is None:
                self._work_s += time.perf_counter() - t0
                continue
            out = self._registered(pair[0][1], pair[1][1])
            self.frame_ms, self._work_s = 1e3 * (self._work_s + time.perf_counter() - t0), 0.0
            return out

    def _registered(self, color, depth) -> RgbdFrame:
        self._pair = {"color": color, "depth": depth}
        self._composer.invoke(color)
        frames = self._composed.wait_for_frame(1000).as_frameset()
        self._pair = {}
        aligned = self.align.process(frames)
        d = aligned.get_depth_frame()
        c = aligned.get_color_frame()
        # copies: the SDK recycles its frames from small pools, so a caller keeping frames
        # (a queue, a test) must not hold the SDK's memory
        return RgbdFrame(color=np.array(self._rgb(c)), depth=np.array(d.get_data()), depth_units=self.depth_units,
                         intrinsics=self.intrinsics, sensor_time=c.get_timestamp() * 1e-3,
                         frame_number=int(c.get_frame_number()), distortion=self.distortion)

    def _rgb(self, frame) -> np.ndarray:
        rs = self.rs
        img = np.asanyarray(frame.get_data())
        fmt = frame.get_profile().format()
        if fmt == rs.format.rgb8:
            return img
        if fmt == rs.format.bgr8:
            return img[..., ::-1]
        if fmt in (rs.format.rgba8, rs.format.bgra8):
            return img[..., :3] if fmt == rs.format.rgba8 else img[..., 2::-1]
        if fmt == rs.format.yuyv:
            import cv2
            return cv2.cvtColor(img.reshape(img.shape[0], -1, 2), cv2.COLOR_YUV2RGB_YUYV)
        raise CameraError(f"RealSense colour format {fmt} is not supported (rgb8, bgr8, rgba8, bgra8, yuyv)")

    def _collect_motion(self) -> None:
        rs = self.rs
        while self._motion:
            kind, t, v = self._motion.popleft()
            v = self._imu_rotation.get(kind, np.eye(3)) @ v
            if kind == rs.stream.accel:
                self._imu.append(ImuSample(t, v))
            elif self._imu and self._imu[-1].gyro is None:
                self._imu[-1].gyro = v
        del self._imu[:-2000]

    def _playback_stopped(self) -> bool:
        try:
            return self.playback.current_status() == self.rs.playback_status.stopped
        except RuntimeError:
            return True

    def close(self) -> None:
        self._closing.set()
        for sensor in self.sensors:
            for step in (sensor.stop, sensor.close):
                try:
                    step()
                except RuntimeError:
                    pass
        self.sensors = []
        while not self._video.empty():
            self._video.get_nowait()
        self._closing.clear()
        self.dev = None
        self.playback = None

    # -- discovery -----------------------------------------------------------------------------
    @classmethod
    def list_devices(cls) -> list[DeviceInfo]:
        rs = sdk_imports.realsense()
        out = []
        for d in rs.context().query_devices():
            details = {"firmware": _info(rs, d, "firmware_version"), "usb": _info(rs, d, "usb_type_descriptor")}
            out.append(DeviceInfo(cls.sdk, _info(rs, d, "serial_number"), _info(rs, d, "name"),
                                  {k: v for k, v in details.items() if v}))
        return out

    @classmethod
    def describe(cls, settings: CameraSettings) -> list[str]:
        rs = sdk_imports.realsense()
        if settings.file:
            driver = cls(settings)
            driver.open()
            try:
                lines = [f"{driver.device.name}: {settings.file}", f"  depth scale {driver.depth_units:g} m/unit",
                         f"  colour intrinsics {_describe_intrinsics(driver.intrinsics)}"]
                lines += [f"  stream {sp.stream_name()} {sp.format()} @ {sp.fps()} Hz" for sp in driver.profiles.values()]
                lines.append(f"  IMU: {'yes' if driver.has_imu else 'no'}")
                return lines
            finally:
                driver.close()
        devices = list(rs.context().query_devices())
        chosen = [d for d in devices if not settings.device or _info(rs, d, "serial_number") == settings.device]
        if not chosen:
            raise NoDevice("no RealSense device connected" if not settings.device
                           else f"no RealSense device with serial number {settings.device}")
        dev = chosen[0]
        lines = [f"{_info(rs, dev, 'name')} serial {_info(rs, dev, 'serial_number')} "
                 f"firmware {_info(rs, dev, 'firmware_version')}"]
        for sensor in dev.query_sensors():
            lines.append(f"  sensor {_info(rs, sensor, 'name')}")
            seen = set()
            for sp in sensor.get_stream_profiles():
                if sp.is_video_stream_profile():
                    v = sp.as_video_stream_profile()
                    key = (sp.stream_name(), v.width(), v.height(), str(sp.format()))
                    if key in seen:
                        continue
                    seen.add(key)
                    fps = sorted({p.fps() for p in sensor.get_stream_profiles() if p.is_video_stream_profile()
                                  and p.stream_name() == sp.stream_name() and p.as_video_stream_profile().width() == v.width()
                                  and p.as_video_stream_profile().height() == v.height() and p.format() == sp.format()})
                    lines.append(f"    {sp.stream_name():8s} {v.width()}x{v.height()} {sp.format()} @ {fps} Hz  "
                                 f"{_describe_intrinsics(_intrinsics(sp))}")
                else:
                    lines.append(f"    {sp.stream_name():8s} {sp.format()} @ {sp.fps()} Hz")
        return lines


def _describe_intrinsics(K: CameraIntrinsics) -> str:
    return f"fx {K.fx:.1f} fy {K.fy:.1f} cx {K.cx:.1f} cy {K.cy:.1f} (hfov {K.hfov_deg:.1f} deg)"
