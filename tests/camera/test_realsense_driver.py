"""RealSense without hardware: a software device recorded by the SDK's own recorder (.db3),
played back through the driver (pipeline, non-real-time playback, rs.align)."""
import numpy as np
import pytest

from raspv_camera.camera_driver import CameraSettings
from raspv_camera.realsense_driver import RealSenseDriver
from raspv_camera.rgbd_frame import EndOfRecording, NoDevice
from raspv_camera.sdk_recordings import SourceFrame, depth_seen_from, write_realsense_recording
from raspv_common.intrinsics import CameraIntrinsics

from .conftest import GRAVITY_C


def read_all(driver, limit=200):
    frames = []
    while len(frames) < limit:
        try:
            f = driver.read(2.0)
        except EndOfRecording:
            return frames
        if f is not None:
            frames.append(f)
    raise AssertionError("the recording did not end")


def test_frames_intrinsics_scale_and_stamps_come_back(realsense_recording):
    rec = realsense_recording
    with RealSenseDriver(CameraSettings(file=str(rec.path))) as driver:
        assert driver.device.name == "Test D435I" and driver.has_imu
        frames = read_all(driver)
        imu = driver.imu_samples()
    # the SDK's playback sometimes holds back the first frame set (reference facts: 29 of 30)
    assert len(frames) >= len(rec.frames) - 1
    numbers = [f.frame_number for f in frames]
    assert numbers == sorted(set(numbers))
    for f in frames:
        src = rec.frames[f.frame_number]
        assert np.array_equal(f.color, src.color)                        # colour bit-exact
        assert f.intrinsics == rec.camera                                 # intrinsics exact
        assert f.depth_units == pytest.approx(0.001)                      # depth scale
        assert f.sensor_time == pytest.approx(src.time, abs=1e-6)        # the recording's own stamps
        # depth and colour share intrinsics and sit at the same place, so the SDK's registration
        # maps each value onto its own pixel; rounding of pixel footprints leaves a few pixels
        # empty and moves a few by one pixel (the pattern's depth grows 1 mm per column)
        mapped = f.depth > 0
        diff = f.depth[mapped].astype(int) - src.depth[mapped].astype(int)
        assert mapped.mean() > 0.9 and (diff == 0).mean() > 0.99 and np.abs(diff).max() <= 1
        metres = f.depth_metres()
        assert np.isnan(metres[~mapped]).all() and metres[0, 5] == pytest.approx(src.depth[0, 5] * 1e-3)
    # the accelerometer comes with the frames, in the colour optical frame (identity extrinsics here)
    assert imu and all(np.allclose(s.accel, GRAVITY_C, atol=1e-5) for s in imu)
    assert all(rec.frames[0].time - 1e-6 <= s.sensor_time <= rec.frames[-1].time + 1e-6 for s in imu)


def test_the_imu_is_turned_into_the_colour_optical_frame_by_the_device_extrinsics():
    """An IMU mounted rotated in the device (a D435i's motion module's axes are not the colour
    camera's): the extrinsics as librealsense stores them (column-major) turn its readings into
    the colour optical frame. (The SDK's recorder does not keep a software device's motion-stream
    extrinsics — "Requested extrinsics are not available" on playback, registered to colour or to
    depth — so the recording tests run with identity; this checks the rotation path itself.)"""
    import types

    from raspv_camera import sdk_imports
    from raspv_camera.realsense_driver import _rotation_to

    rs = sdk_imports.realsense()

    def rot(axis, deg):
        c, s_ = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        i, j = [k for k in range(3) if k != axis]
        R = np.eye(3)
        R[i, i], R[i, j], R[j, i], R[j, j] = c, -s_, s_, c
        return R
    color_from_imu = rot(2, 90.0) @ rot(0, 20.0)                # 90° about z after 20° about x: no symmetry
    stored = types.SimpleNamespace(rotation=list(color_from_imu.T.ravel()), translation=[0.0, 0.0, 0.0])
    imu_profile = types.SimpleNamespace(get_extrinsics_to=lambda dst: stored)
    assert np.allclose(_rotation_to(imu_profile, None), color_from_imu)
    driver = RealSenseDriver(CameraSettings())
    driver._imu_rotation = {rs.stream.accel: _rotation_to(imu_profile, None),
                            rs.stream.gyro: _rotation_to(imu_profile, None)}
    gyro_c = np.array([0.1, -0.2, 0.3])
    driver._motion.extend([(rs.stream.accel, 1.0, color_from_imu.T @ GRAVITY_C),     # read in the IMU's axes
                           (rs.stream.gyro, 1.0, color_from_imu.T @ gyro_c)])
    driver._collect_motion()
    [sample] = driver.imu_samples()
    assert not np.allclose(color_from_imu.T @ GRAVITY_C, GRAVITY_C, atol=0.5)
    assert np.allclose(sample.accel, GRAVITY_C) and np.allclose(sample.gyro, gyro_c)
    # a rotation that is not one (a bad calibration) is ignored rather than skewing gravity
    bad = types.SimpleNamespace(get_extrinsics_to=lambda dst: types.SimpleNamespace(rotation=[2.0] + [0.0] * 8))
    assert np.array_equal(_rotation_to(bad, None), np.eye(3))


def test_registration_undoes_a_depth_camera_beside_the_colour_camera(tmp_path, tum_frame):
    _, depth, K = tum_frame                         # registered depth of a real Kinect frame
    depth_cam = CameraIntrinsics(640, 480, 400.0, 400.0, 320.5, 238.5)   # wider, elsewhere
    baseline = (0.025, 0.0, 0.0)
    raw = np.nan_to_num(depth_seen_from(depth, K, depth_cam, baseline) * 1000).astype(np.uint16)
    path = write_realsense_recording(tmp_path / "tum.db3", [SourceFrame(np.zeros((480, 640, 3), np.uint8), raw, 1.0)] * 3,
                                     K, depth_cam, depth_to_color_m=baseline)
    with RealSenseDriver(CameraSettings(file=str(path))) as driver:
        frame = read_all(driver)[-1]
    out = frame.depth_metres()
    both = np.isfinite(out) & np.isfinite(depth)
    assert both.sum() > 0.85 * np.isfinite(depth).sum()
    # back where the colour camera sees it: the median within the 1 mm quantisation; pixels near
    # depth edges (16 % of this frame's readings lie within 2 px of a jump > 5 cm) are resampled
    # twice and may take the other side's depth
    err = np.abs(out[both] - depth[both])
    assert np.median(err) < 0.002 and np.mean(err < 0.02) > 0.9
    unregistered = np.abs(raw.astype(np.float32) * 1e-3 - depth)
    assert np.nanmedian(unregistered[both & (raw > 0)]) > 10 * np.median(err)   # registration did something


def test_depth_units_other_than_millimetres(tmp_path):
    K = CameraIntrinsics(32, 24, 30.0, 30.0, 15.5, 11.5)
    frames = [SourceFrame(np.zeros((24, 32, 3), np.uint8), np.full((24, 32), 4000, np.uint16), i / 30) for i in range(3)]
    path = write_realsense_recording(tmp_path / "units.db3", frames, K, depth_units=0.00025)   # L515-style 0.25 mm
    with RealSenseDriver(CameraSettings(file=str(path))) as driver:
        f = read_all(driver)[-1]
    assert f.depth_units == pytest.approx(0.00025)
    assert np.nanmedian(f.depth_metres()) == pytest.approx(1.0, abs=1e-6)


def test_no_device_and_missing_file_are_one_line_errors(tmp_path):
    assert RealSenseDriver.list_devices() == []
    with pytest.raises(NoDevice, match="no RealSense device connected"):
        RealSenseDriver(CameraSettings()).open()
    with pytest.raises(NoDevice, match="no such recording"):
        RealSenseDriver(CameraSettings(file=str(tmp_path / "gone.db3"))).open()
    junk = tmp_path / "junk.db3"
    junk.write_bytes(b"not a recording" * 10)
    with pytest.raises(NoDevice, match="cannot start"):
        RealSenseDriver(CameraSettings(file=str(junk))).open()
