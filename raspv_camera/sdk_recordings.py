"""Native recordings written by each vendor's own SDK, without hardware (no ROS).

These are what the tests and ``raspv bench camera`` play through the `camera` node, and a way to
turn any RGB-D frames into a file the SDK's own tools open:

- :func:`write_realsense_recording`: a ``rs.software_device`` with a depth sensor (z16, the
  given depth units) and a colour sensor (rgb8), each with its own intrinsics, the extrinsics
  between them and optionally an accelerometer, recorded by the SDK's ``rs.recorder`` (SDK ≥
  2.58 writes ROS 2 ``.db3``).
- :func:`write_openni2_dummy_recording`: Debian's OpenNI2 dummy device (synthetic 320×240 depth
  and RGB) recorded by ``openni2.Recorder`` to ``.oni``, then :func:`add_oni_cropping`.
- :func:`write_depthai_recording`: host-only DepthAI pipelines (no device) feeding RAW16 depth
  and RGB888i colour ``ImgFrame`` s, intrinsics attached, to two ``RecordMessage`` nodes
  (``depth.mcap``, ``color.mcap`` in a directory).
"""
from __future__ import annotations

import datetime
import struct
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from raspv_camera import sdk_imports
from raspv_camera.rgbd_frame import CameraError
from raspv_common.intrinsics import CameraIntrinsics


@dataclass
class SourceFrame:
    """One frame to record: ``color`` (H, W, 3) uint8 RGB, ``depth`` (H, W) uint16 in the
    recording's depth units, ``time`` [s] on the recording's clock, optional ``accel`` (3,)
    [m/s²] in the depth camera's optical frame."""

    color: np.ndarray
    depth: np.ndarray
    time: float
    accel: np.ndarray | None = None


# -- RealSense ---------------------------------------------------------------------------------
def write_realsense_recording(path: str | Path, frames: Iterable[SourceFrame], color_camera: CameraIntrinsics,
                              depth_camera: CameraIntrinsics | None = None, depth_units: float = 0.001,
                              fps: int = 30, depth_to_color_m: Sequence[float] = (0.0, 0.0, 0.0),
                              name: str = "RASPV software device", serial: str = "000000000000",
                              with_accel: bool = False, color_lens: tuple[str, Sequence[float]] | None = None) -> Path:
    """Record ``frames`` through a RealSense software device with the SDK's recorder. Depth and
    colour have their own intrinsics (depth defaults to colour's) and the depth camera sits at
    ``depth_to_color_m`` in the colour frame (no rotation); ``color_lens`` the colour stream's
    librealsense distortion model name and five coefficients (none by default). Returns the file
    written."""
    rs = sdk_imports.realsense()
    path = Path(path)
    if path.suffix != ".db3":
        raise CameraError(f"{path}: the RealSense recorder (SDK >= 2.58) writes .db3 files")
    path.parent.mkdir(parents=True, exist_ok=True)
    depth_camera = depth_camera or color_camera
    dev = rs.software_device()
    dev.register_info(rs.camera_info.name, name)
    dev.register_info(rs.camera_info.serial_number, serial)
    depth_sensor = dev.add_sensor("Stereo Module")
    color_sensor = dev.add_sensor("RGB Camera")
    depth_sensor.add_read_only_option(rs.option.depth_units, float(depth_units))
    d_prof = depth_sensor.add_video_stream(_video_stream(rs, rs.stream.depth, 0, depth_camera, fps, 2, rs.format.z16))
    c_prof = color_sensor.add_video_stream(_video_stream(rs, rs.stream.color, 1, color_camera, fps, 3, rs.format.rgb8,
                                                         color_lens))
    ext = rs.extrinsics()
    ext.rotation = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    ext.translation = [float(v) for v in depth_to_color_m]
    d_prof.register_extrinsics_to(c_prof, ext)
    sensors = [(depth_sensor, d_prof), (color_sensor, c_prof)]
    a_prof = None
    if with_accel:
        motion_sensor = dev.add_sensor("Motion Module")
        ms = rs.motion_stream()
        ms.type, ms.index, ms.uid, ms.fps, ms.fmt = rs.stream.accel, 0, 2, 200, rs.format.motion_xyz32f
        mi = rs.motion_device_intrinsic()
        mi.data = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]
        mi.noise_variances = [0.0, 0.0, 0.0]
        mi.bias_variances = [0.0, 0.0, 0.0]
        ms.intrinsics = mi
        a_prof = motion_sensor.add_motion_stream(ms)
        sensors.append((motion_sensor, a_prof))
    dev.create_matcher(rs.matchers.dlr_c)
    recorder = rs.recorder(str(path), dev)
    sink = rs.syncer(100)
    for sensor, prof in sensors:
        sensor.open(prof)
        sensor.start(sink)
    try:
        for i, f in enumerate(frames):
            ms_time = float(f.time) * 1e3
            if a_prof is not None and f.accel is not None:
                m = rs.software_motion_frame()
                v = rs.vector()
                v.x, v.y, v.z = (float(x) for x in f.accel)
                m.data, m.timestamp, m.domain, m.frame_number = v, ms_time, rs.timestamp_domain.hardware_clock, i
                m.profile = a_prof.as_motion_stream_profile()
                sensors[2][0].on_motion_frame(m)
            for (sensor, prof), pixels, bpp in ((sensors[0], np.ascontiguousarray(f.depth, np.uint16), 2),
                                                (sensors[1], np.ascontiguousarray(f.color, np.uint8), 3)):
                vf = rs.software_video_frame()
                vf.pixels, vf.bpp, vf.stride = pixels, bpp, pixels.shape[1] * bpp
                vf.timestamp, vf.domain, vf.frame_number = ms_time, rs.timestamp_domain.hardware_clock, i
                vf.profile = prof.as_video_stream_profile()
                if bpp == 2:
                    vf.depth_units = float(depth_units)
                sensor.on_video_frame(vf)
            while sink.poll_for_frames():     # keep the syncer's queue short
                pass
    finally:
        for sensor, _ in sensors:
            sensor.stop()
            sensor.close()
        del recorder                          # the recorder writes its index when released
    return path


def _video_stream(rs, kind, uid: int, K: CameraIntrinsics, fps: int, bpp: int, fmt,
                  lens: tuple[str, Sequence[float]] | None = None):
    intr = rs.intrinsics()
    intr.width, intr.height = K.width, K.height
    intr.fx, intr.fy, intr.ppx, intr.ppy = K.fx, K.fy, K.cx, K.cy
    model, coeffs = lens or ("none", [0.0] * 5)
    intr.model, intr.coeffs = getattr(rs.distortion, model), [float(c) for c in coeffs]
    vs = rs.video_stream()
    vs.type, vs.index, vs.uid = kind, 0, uid
    vs.width, vs.height, vs.fps, vs.bpp, vs.fmt, vs.intrinsics = K.width, K.height, fps, bpp, fmt, intr
    return vs


# -- OpenNI2 -------------------------------------------------------------------------------------
_ONI_RECORD = struct.Struct("<IIIIIQ")      # magic, type, node id, fields size, payload size, undo position
_ONI_MAGIC = 0x0052494E                     # "NIR\0"
_ONI_GENERAL_PROPERTY = 6
_ONI_CROPPING = struct.Struct("<IHHHH")     # XnCropping: XnBool enabled, x/y offset, x/y size


def _oni_records(buf: bytes | bytearray):
    """(offset, type, node id, fields size, property name or None) of each record of an ONI file."""
    off = 24                                # after the file header
    while off + _ONI_RECORD.size <= len(buf):
        magic, kind, node, fields, payload, _ = _ONI_RECORD.unpack_from(buf, off)
        if magic != _ONI_MAGIC or fields < _ONI_RECORD.size:
            return
        name = None
        if kind in (3, 4, 5, 6) and fields >= _ONI_RECORD.size + 4:
            n = struct.unpack_from("<I", buf, off + _ONI_RECORD.size)[0]
            start = off + _ONI_RECORD.size + 4
            name = bytes(buf[start:start + n]).split(b"\0")[0].decode("latin-1")
        yield off, kind, node, fields, name
        off += fields + payload


def add_oni_cropping(path: str | Path) -> int:
    """Give every stream of an ONI recording a (disabled) cropping property, in place.

    OpenNI2's file player drops every frame of a stream whose recording has no ``xnCropping``
    record, and devices without a cropping property (the dummy device) write none. Each
    stream's ``xnSupportedPixelFormats`` record (64 bytes, not read by the player) is replaced
    by an ``xnCropping`` record of the same length (the name padded with NULs), so no offset in
    the file moves. Returns the number of streams fixed."""
    path = Path(path)
    buf = bytearray(path.read_bytes())
    records = list(_oni_records(buf))
    have = {node for _, _, node, _, name in records if name == "xnCropping"}
    fixed = 0
    for off, kind, node, fields, name in records:
        if kind != _ONI_GENERAL_PROPERTY or name != "xnSupportedPixelFormats" or node in have:
            continue
        name_len = fields - _ONI_RECORD.size - 4 - 4 - _ONI_CROPPING.size
        if name_len < len("xnCropping") + 1:
            continue
        record = (bytes(buf[off:off + _ONI_RECORD.size]) + struct.pack("<I", name_len)
                  + b"xnCropping".ljust(name_len, b"\0") + struct.pack("<I", _ONI_CROPPING.size)
                  + _ONI_CROPPING.pack(0, 0, 0, 0, 0))
        buf[off:off + fields] = record
        have.add(node)
        fixed += 1
    if fixed:
        path.write_bytes(bytes(buf))
    return fixed


def write_openni2_dummy_recording(path: str | Path, frames: int = 30) -> tuple[Path, list[tuple[int, np.ndarray, np.ndarray]]]:
    """Record ``frames`` frames of OpenNI2's dummy device (320×240 depth in mm + RGB) to an
    ``.oni`` file with the SDK's recorder, fix it with :func:`add_oni_cropping`, and return
    the path and what was recorded: (frame index, depth (240, 320) uint16, colour (240, 320, 3))."""
    ni = sdk_imports.openni2()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        dev = ni.Device(b"Dummy")
    except Exception as exc:
        raise CameraError(f"OpenNI2's dummy device is not available ({exc}); it comes with libopenni2-0") from None
    depth_stream, color_stream = dev.create_depth_stream(), dev.create_color_stream()
    recorder = ni.Recorder(str(path).encode())
    recorder.attach(depth_stream)
    recorder.attach(color_stream)
    recorded = []
    depth_stream.start()
    color_stream.start()
    recorder.start()
    try:
        for _ in range(frames):
            fd, fc = depth_stream.read_frame(), color_stream.read_frame()    # read every started stream
            d = np.frombuffer(fd.get_buffer_as_uint16(), np.uint16).reshape(fd.height, fd.width).copy()
            c = np.frombuffer(fc.get_buffer_as_uint8(), np.uint8).reshape(fc.height, fc.width, 3).copy()
            recorded.append((int(fd.frameIndex), d, c))
    finally:
        # stop the streams before destroying the recorder: oniRecorderDestroy takes a lock a
        # streaming thread may hold while it hands a frame to the recorder (a deadlock seen here)
        recorder.stop()
        depth_stream.stop()
        color_stream.stop()
        time.sleep(0.2)          # the dummy driver may crash when closed right after stopping
        recorder.close()
        dev.close()
    if add_oni_cropping(path) == 0:
        raise CameraError(f"{path}: could not add the cropping records the OpenNI2 player needs")
    return path, recorded


# -- DepthAI -------------------------------------------------------------------------------------
def _imgframe(dai, data: np.ndarray, kind, seq: int, t: float, K: CameraIntrinsics, lens: Sequence[float] = ()):
    f = dai.ImgFrame()
    h, w = data.shape[:2]
    f.setWidth(w)
    f.setHeight(h)
    f.setType(kind)
    f.setStride(w * data.itemsize * (data.shape[2] if data.ndim == 3 else 1))
    f.setData(np.ascontiguousarray(data).reshape(-1).view(np.uint8))
    f.setSequenceNum(seq)
    stamp = datetime.timedelta(seconds=float(t))
    f.setTimestamp(stamp)
    f.setTimestampDevice(stamp)
    transformation = dai.ImgTransformation(w, h, K.K.tolist())
    if len(lens):
        transformation.setDistortionModel(dai.CameraModel.Perspective)
        transformation.setDistortionCoefficients([float(c) for c in lens] + [0.0] * (14 - len(lens)))
    f.setTransformation(transformation)
    return f


def write_depthai_recording(directory: str | Path, frames: Iterable[SourceFrame], camera: CameraIntrinsics,
                            pace_s: float = 0.0, lens: Sequence[float] = ()) -> Path:
    """Record RGB-D ``frames`` (depth in mm, registered to colour, both described by
    ``camera`` and the OpenCV distortion coefficients ``lens``) with DepthAI host-only
    ``RecordMessage`` nodes into ``directory`` (``depth.mcap`` RAW16, ``color.mcap`` RGB888i).
    ``pace_s`` waits between frames."""
    dai = sdk_imports.depthai()
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    with dai.Pipeline(False) as pipeline:
        rec_depth = pipeline.create(dai.node.RecordMessage)
        rec_depth.setRecordFile(str(out / "depth.mcap"))
        rec_color = pipeline.create(dai.node.RecordMessage)
        rec_color.setRecordFile(str(out / "color.mcap"))
        q_depth = rec_depth.input.createInputQueue(maxSize=8, blocking=True)
        q_color = rec_color.input.createInputQueue(maxSize=8, blocking=True)
        pipeline.start()
        for i, f in enumerate(frames):
            q_depth.send(_imgframe(dai, np.asarray(f.depth, np.uint16), dai.ImgFrame.Type.RAW16, i, f.time, camera, lens))
            q_color.send(_imgframe(dai, np.asarray(f.color, np.uint8), dai.ImgFrame.Type.RGB888i, i, f.time, camera,
                                   lens))
            if pace_s:
                time.sleep(pace_s)
        # let the recorders take what is queued: createInputQueue puts a host InputQueue node
        # (with its own buffer) in front of each recorder, so every node's inputs must drain
        inputs = [i for node in pipeline.getAllNodes() for i in node.getInputRefs()]
        deadline = time.monotonic() + 10.0
        quiet_since = None
        while time.monotonic() < deadline:
            if any(i.getSize() for i in inputs):
                quiet_since = None
            elif quiet_since is None:
                quiet_since = time.monotonic()
            elif time.monotonic() - quiet_since > 0.2:      # the last message taken is written
                break
            time.sleep(0.01)
        pipeline.stop()
    return out


def depth_seen_from(depth_m: np.ndarray, camera: CameraIntrinsics, other: CameraIntrinsics,
                    other_from_camera_m: Sequence[float]) -> np.ndarray:
    """The depth image [m] (NaN holes) that a second camera ``other``, translated by
    ``other_from_camera_m`` (its origin in ``camera``'s frame, no rotation), sees of the surface
    in ``depth_m`` (as seen by ``camera``): each point is moved into the other camera, projected
    and z-buffered (nearest wins). Builds the unregistered depth of a stereo/ToF sensor from a
    registered frame, so an SDK's registration has real work to undo."""
    h, w = depth_m.shape
    v, u = np.mgrid[0:h, 0:w]
    z = depth_m.astype(np.float64)
    ok = np.isfinite(z) & (z > 0)
    x = (u[ok] - camera.cx) / camera.fx * z[ok] - other_from_camera_m[0]
    y = (v[ok] - camera.cy) / camera.fy * z[ok] - other_from_camera_m[1]
    zz = z[ok] - other_from_camera_m[2]
    front = zz > 1e-3
    x, y, zz = x[front], y[front], zz[front]
    uu = np.rint(x / zz * other.fx + other.cx).astype(np.int64)
    vv = np.rint(y / zz * other.fy + other.cy).astype(np.int64)
    inside = (uu >= 0) & (uu < other.width) & (vv >= 0) & (vv < other.height)
    flat = vv[inside] * other.width + uu[inside]
    out = np.full(other.width * other.height, np.inf)
    np.minimum.at(out, flat, zz[inside])
    out[~np.isfinite(out)] = np.nan
    return out.reshape(other.height, other.width).astype(np.float32)
