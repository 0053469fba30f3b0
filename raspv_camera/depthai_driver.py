"""Luxonis OAK cameras through ``depthai`` 3.x (no ROS): live devices by device id (MxId) or
name, or a recording made with DepthAI's ``RecordMessage`` nodes.

Live: the colour camera (CAM_A) at the size asked, stereo depth from CAM_B/CAM_C aligned to
CAM_A on the device (``StereoDepth.setDepthAlign``; ``ImageAlign`` on RVC4), both paired by a
``Sync`` node; depth is RAW16 millimetres. The accelerometer (OAK-D and later) is read when
present and rotated into the colour camera's optical frame with the device's calibration; a
device whose calibration has no such rotation runs without the IMU, saying so in one line.
Device search uses ``Device.getAllAvailableDevices()`` (≈0.5 s) before opening anything, so no
device is a quick, clean error; opening uses ``DEPTHAI_SEARCH_TIMEOUT`` (``search_timeout``).

Recording (``file:``): a directory of ``.mcap`` files written by ``RecordMessage`` (or one of
them): the stream whose frames are RAW16 is depth (millimetres, registered to colour), the
one with colour frames (RGB888i/BGR888i/NV12/planar) is colour. They are replayed by host-only
``ReplayMessage`` nodes (no device needed; RAW16 comes back bit-exact) and paired by sequence
number. Intrinsics come with each frame (``ImgFrame.getTransformation()``). ``ReplayMessage``
paces frames by their recorded times itself.
"""
from __future__ import annotations

import datetime
import os
import sys
import time
from pathlib import Path

import numpy as np

from raspv_camera import lens_distortion, sdk_imports
from raspv_camera.camera_driver import CameraDriver, CameraSettings
from raspv_camera.rgbd_frame import (CameraError, DeviceInfo, DeviceLost, EndOfRecording, ImuSample, NoDevice,
                                     RgbdFrame)
from raspv_common.intrinsics import CameraIntrinsics

STEREO_SIZE = (640, 400)     # mono camera resolution fed to stereo [px]


def recording_files(path: str | Path) -> list[Path]:
    """The ``.mcap`` files of a DepthAI recording given as a directory or one of its files."""
    p = Path(path).expanduser()
    folder = p if p.is_dir() else p.parent
    return sorted(folder.glob("*.mcap"))


def _intrinsics(frame) -> CameraIntrinsics | None:
    try:
        K = np.asarray(frame.getTransformation().getIntrinsicMatrix(), dtype=np.float64)
    except Exception:
        return None
    if K.shape != (3, 3) or not (K[0, 0] > 0 and K[1, 1] > 0):
        return None
    return CameraIntrinsics.from_matrix(K, frame.getWidth(), frame.getHeight())


class ImuCalibrationError(CameraError):
    """The device's calibration has no usable IMU → colour camera rotation."""


def imu_to_camera_rotation(calibration, dai) -> np.ndarray:
    """(3, 3) rotation taking IMU axes to the colour camera's (CAM_A) optical frame, from a
    ``dai.CalibrationHandler``; :class:`ImuCalibrationError` (one line) when the calibration
    has none — never a guessed identity (a wrong gravity, silently)."""
    try:
        T = np.asarray(calibration.getImuToCameraExtrinsics(dai.CameraBoardSocket.CAM_A, True), dtype=np.float64)
    except RuntimeError as exc:                  # depthai: "IMU calibration data is not available …"
        raise ImuCalibrationError(f"no IMU-to-camera rotation in the device calibration ({exc})") from None
    return T[:3, :3]                             # depthai keeps it a rotation (orthonormal, det 1) when set


class DepthAIDriver(CameraDriver):
    sdk = "depthai"
    file_suffixes = (".mcap",)

    def __init__(self, settings: CameraSettings) -> None:
        super().__init__(settings)
        self.dai = sdk_imports.depthai()
        self.pipeline = None
        self.device_handle = None
        self.queues: dict[str, object] = {}
        self.imu_queue = None
        self.imu_rotation: np.ndarray | None = None    # IMU → colour optical frame, from the calibration
        self.intrinsics: CameraIntrinsics | None = None
        self._said_distortion = False
        self._pending: dict[str, dict[int, object]] = {"depth": {}, "color": {}}
        self._unclassified: list[tuple[Path, object]] = []

    # -- open ----------------------------------------------------------------------------------
    def open(self) -> DeviceInfo:
        if self.is_file:
            return self._open_recording()
        return self._open_device()

    def _open_recording(self) -> DeviceInfo:
        dai = self.dai
        path = self.check_file()
        files = recording_files(path)
        if len(files) < 2:
            raise NoDevice(f"{path}: a DepthAI recording needs a depth and a colour .mcap file "
                           f"(found {len(files)})")
        self.pipeline = dai.Pipeline(False)
        try:
            for f in files:
                node = self.pipeline.create(dai.node.ReplayMessage)
                node.setReplayFile(str(f))
                node.setLoop(False)
                self._unclassified.append((f, node.out.createOutputQueue(maxSize=8, blocking=True)))
            self.pipeline.start()
        except Exception as exc:
            self.close()
            raise NoDevice(f"{path}: DepthAI cannot replay it ({exc})") from None
        self.device = DeviceInfo(self.sdk, str(path), "DepthAI recording", {"files": ", ".join(f.name for f in files)})
        return self.device

    def _open_device(self) -> DeviceInfo:
        dai = self.dai
        s = self.settings
        available = dai.Device.getAllAvailableDevices()
        if not available:
            raise NoDevice("no DepthAI (OAK) device found")
        chosen = available[0]
        if s.device:
            match = [d for d in available if s.device in (d.getDeviceId(), d.name)]
            if not match:
                raise NoDevice(f"no DepthAI device {s.device} (found: {', '.join(d.getDeviceId() for d in available)})")
            chosen = match[0]
        os.environ["DEPTHAI_SEARCH_TIMEOUT"] = str(int(s.search_timeout * 1000))
        try:
            self.device_handle = dai.Device(chosen)
        except RuntimeError as exc:
            raise NoDevice(f"cannot open DepthAI device {chosen.getDeviceId()}: {exc}") from None
        try:
            self._build_live_pipeline()
        except Exception as exc:
            self.close()
            raise CameraError(f"DepthAI pipeline could not start on {chosen.getDeviceId()}: {exc}") from None
        self.device = DeviceInfo(self.sdk, chosen.getDeviceId(), self.device_handle.getDeviceName(),
                                 {"usb": str(self.device_handle.getUsbSpeed()).split(".")[-1]})
        return self.device

    def _build_live_pipeline(self) -> None:
        dai = self.dai
        s = self.settings
        dev = self.device_handle
        p = dai.Pipeline(dev)
        cam = p.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_A)
        rgb = cam.requestOutput((s.width, s.height), dai.ImgFrame.Type.RGB888i, fps=float(s.fps))
        left = p.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_B)
        right = p.create(dai.node.Camera).build(dai.CameraBoardSocket.CAM_C)
        stereo = p.create(dai.node.StereoDepth)
        left.requestOutput(STEREO_SIZE, fps=float(s.fps)).link(stereo.left)
        right.requestOutput(STEREO_SIZE, fps=float(s.fps)).link(stereo.right)
        stereo.setLeftRightCheck(True)
        sync = p.create(dai.node.Sync)
        sync.setSyncThreshold(datetime.timedelta(seconds=0.5 / s.fps))
        rgb.link(sync.inputs["color"])
        if dev.getPlatform() == dai.Platform.RVC4:
            align = p.create(dai.node.ImageAlign)
            stereo.depth.link(align.input)
            rgb.link(align.inputAlignTo)
            align.outputAligned.link(sync.inputs["depth"])
        else:
            stereo.setDepthAlign(dai.CameraBoardSocket.CAM_A)
            stereo.setOutputSize(s.width, s.height)
            stereo.depth.link(sync.inputs["depth"])
        self.queues = {"sync": sync.out.createOutputQueue(maxSize=4, blocking=False)}
        if s.imu and dev.getConnectedIMU() not in ("", "NONE"):
            try:
                self.imu_rotation = imu_to_camera_rotation(dev.readCalibration(), dai)
            except ImuCalibrationError as exc:     # refused: a guessed rotation would give a wrong gravity
                print(f"camera: DepthAI {dev.getDeviceId()}: IMU off: {exc}", file=sys.stderr, flush=True)
            else:
                imu = p.create(dai.node.IMU)
                imu.enableIMUSensor(dai.IMUSensor.ACCELEROMETER_CALIBRATED, 100)
                imu.setBatchReportThreshold(1)
                imu.setMaxBatchReports(10)
                self.imu_queue = imu.out.createOutputQueue(maxSize=50, blocking=False)
                self.has_imu = True
        self.pipeline = p
        p.start()

    # -- read ----------------------------------------------------------------------------------
    def read(self, timeout_s: float) -> RgbdFrame | None:
        if self.pipeline is None:
            raise DeviceLost("the DepthAI pipeline is not running")
        if self.is_file:
            return self._read_recording(timeout_s)
        return self._read_device(timeout_s)

    def _read_device(self, timeout_s: float) -> RgbdFrame | None:
        dai = self.dai
        if self.device_handle.isClosed() or not self.pipeline.isRunning():
            raise DeviceLost("the DepthAI device closed (unplugged or crashed)")
        try:
            group = self.queues["sync"].get(datetime.timedelta(seconds=timeout_s))
        except (RuntimeError, dai.MessageQueue.QueueException) as exc:
            raise DeviceLost(f"DepthAI: {exc}") from None
        self._drain_imu()
        if group is None:
            return None
        color, depth = group["color"], group["depth"]
        return self._frame(color, depth)

    def _drain_imu(self) -> None:
        if self.imu_queue is None:
            return
        for packet in self.imu_queue.tryGetAll():
            for p in packet.packets:
                a = p.acceleroMeter
                t = a.getTimestampDevice().total_seconds()
                self._imu.append(ImuSample(t, self.imu_rotation @ np.array([a.x, a.y, a.z], dtype=np.float64)))
        del self._imu[:-200]

    def _read_recording(self, timeout_s: float) -> RgbdFrame | None:
        dai = self.dai
        deadline = time.monotonic() + timeout_s
        try:
            while self._unclassified:
                path, q = self._unclassified[0]
                msg = q.get(datetime.timedelta(seconds=max(0.0, deadline - time.monotonic())))
                if msg is None:
                    return None
                self._unclassified.pop(0)
                kind = self._kind(msg)
                if kind is None or kind in self.queues:
                    continue                    # another stream (IMU, encoded video …) or a duplicate
                self.queues[kind] = q
                self._pending[kind][msg.getSequenceNum()] = msg
            if set(self.queues) != {"depth", "color"}:
                raise EndOfRecording(f"{self.settings.file}: the recording has no "
                                     f"{'depth (RAW16)' if 'depth' not in self.queues else 'colour'} stream")
            while time.monotonic() < deadline:
                common = set(self._pending["depth"]) & set(self._pending["color"])
                if common:
                    seq = min(common)
                    for kind in ("depth", "color"):     # frames older than the pair lost their partner
                        for k in [k for k in self._pending[kind] if k <= seq]:
                            msg = self._pending[kind].pop(k)
                            if k == seq:
                                if kind == "depth":
                                    depth = msg
                                else:
                                    color = msg
                    return self._frame(color, depth)
                kind = "depth" if len(self._pending["depth"]) <= len(self._pending["color"]) else "color"
                msg = self.queues[kind].get(datetime.timedelta(seconds=max(0.0, deadline - time.monotonic())))
                if msg is None:
                    return None
                self._pending[kind][msg.getSequenceNum()] = msg
            return None
        except dai.MessageQueue.QueueException:
            raise EndOfRecording(f"{self.settings.file}: end of recording") from None

    def _kind(self, msg) -> str | None:
        T = self.dai.ImgFrame.Type
        if not isinstance(msg, self.dai.ImgFrame):
            return None
        t = msg.getType()
        if t == T.RAW16:
            return "depth"
        if t in (T.RGB888i, T.BGR888i, T.RGB888p, T.BGR888p, T.NV12, T.YUV420p):
            return "color"
        return None

    def _frame(self, color, depth) -> RgbdFrame:
        t0 = time.perf_counter()
        out = self._convert(color, depth)
        self.frame_ms = 1e3 * (time.perf_counter() - t0)
        return out

    def _convert(self, color, depth) -> RgbdFrame:
        T = self.dai.ImgFrame.Type
        if color.getType() == T.RGB888i:
            rgb = np.asarray(color.getData()).reshape(color.getHeight(), color.getWidth(), 3)
        else:
            rgb = np.ascontiguousarray(color.getCvFrame()[..., ::-1])      # getCvFrame gives BGR
        d = depth.getFrame()
        if d.shape != rgb.shape[:2]:
            import cv2
            d = cv2.resize(d, (rgb.shape[1], rgb.shape[0]), interpolation=cv2.INTER_NEAREST)
        K = _intrinsics(color) or _intrinsics(depth) or self.intrinsics
        if K is None:
            raise CameraError("DepthAI frames carry no intrinsics (ImgTransformation); cannot publish camera info")
        if (K.width, K.height) != (rgb.shape[1], rgb.shape[0]):
            K = K.scaled(rgb.shape[1], rgb.shape[0])
        self.intrinsics = K
        return RgbdFrame(color=rgb, depth=d, depth_units=0.001, intrinsics=K,
                         sensor_time=color.getTimestampDevice().total_seconds(), frame_number=int(color.getSequenceNum()),
                         distortion=self._colour_distortion(color))

    def _colour_distortion(self, color) -> tuple[float, ...]:
        """The colour lens's OpenCV coefficients (its ImgTransformation's model); one a CameraInfo
        cannot carry is said once and the images are published as rectified."""
        t = color.getTransformation()
        try:
            return lens_distortion.from_depthai(t.getDistortionModel().name, list(t.getDistortionCoefficients()))
        except lens_distortion.UnsupportedDistortion as exc:
            if not self._said_distortion:
                print(f"camera: DepthAI colour {exc}: publishing it as rectified", file=sys.stderr, flush=True)
                self._said_distortion = True
            return ()

    def close(self) -> None:
        if self.pipeline is not None:
            try:
                self.pipeline.stop()
            except Exception:
                pass
            self.pipeline = None
        if self.device_handle is not None:
            try:
                self.device_handle.close()
            except Exception:
                pass
            self.device_handle = None
        self.queues = {}
        self._unclassified = []
        self._pending = {"depth": {}, "color": {}}

    # -- discovery -----------------------------------------------------------------------------
    @classmethod
    def list_devices(cls) -> list[DeviceInfo]:
        dai = sdk_imports.depthai()
        return [DeviceInfo(cls.sdk, d.getDeviceId(), d.name, {"state": str(d.state).split(".")[-1],
                                                              "platform": str(d.platform).split(".")[-1]})
                for d in dai.Device.getAllAvailableDevices()]

    @classmethod
    def describe(cls, settings: CameraSettings) -> list[str]:
        dai = sdk_imports.depthai()
        if settings.file:
            driver = cls(settings)
            driver.open()
            try:
                frame = driver.read(5.0)
                lines = [f"DepthAI recording {settings.file}: {driver.device.details['files']}"]
                if frame is not None:
                    lines.append(f"  first frame {frame.color.shape[1]}x{frame.color.shape[0]}, depth in mm, "
                                 f"intrinsics fx {frame.intrinsics.fx:.1f} fy {frame.intrinsics.fy:.1f} "
                                 f"cx {frame.intrinsics.cx:.1f} cy {frame.intrinsics.cy:.1f}")
                return lines
            finally:
                driver.close()
        available = dai.Device.getAllAvailableDevices()
        match = [d for d in available if not settings.device or settings.device in (d.getDeviceId(), d.name)]
        if not match:
            raise NoDevice("no DepthAI (OAK) device found" if not settings.device
                           else f"no DepthAI device {settings.device}")
        os.environ["DEPTHAI_SEARCH_TIMEOUT"] = str(int(settings.search_timeout * 1000))
        with dai.Device(match[0]) as dev:
            calib = dev.readCalibration()
            lines = [f"{dev.getDeviceName()} {match[0].getDeviceId()} ({dev.getPlatformAsString()}), "
                     f"IMU {dev.getConnectedIMU() or 'none'}"]
            for feat in dev.getConnectedCameraFeatures():
                lines.append(f"  {feat.socket}: {feat.sensorName} {feat.width}x{feat.height}")
                try:
                    K = calib.getCameraIntrinsics(feat.socket, feat.width, feat.height)
                    lines.append(f"    fx {K[0][0]:.1f} fy {K[1][1]:.1f} cx {K[0][2]:.1f} cy {K[1][2]:.1f}")
                except RuntimeError:
                    pass
            return lines
