"""DepthAI without hardware: host-only pipelines record RAW16 depth and RGB frames with
RecordMessage and the driver replays them with ReplayMessage; device search with no device."""
import time

import numpy as np
import pytest

from raspv_camera.camera_driver import CameraSettings
from raspv_camera.depthai_driver import DepthAIDriver, ImuCalibrationError, imu_to_camera_rotation
from raspv_camera.rgbd_frame import EndOfRecording, NoDevice

from .conftest import DEPTHAI_LENS


def read_all(d, limit=200, stall_s=60.0):
    out = []
    last = time.monotonic()
    while len(out) < limit:
        try:
            f = d.read(1.0)
        except EndOfRecording:
            return out
        if f is None:                       # a loaded machine may hold the replay threads back
            assert time.monotonic() - last < stall_s, "the replay stalled"
            continue
        last = time.monotonic()
        out.append(f)
    raise AssertionError("the replay did not end")


def test_raw16_depth_colour_intrinsics_and_stamps_come_back_exactly(depthai_recording):
    rec = depthai_recording
    with DepthAIDriver(CameraSettings(file=str(rec.path))) as d:
        frames = read_all(d)
    # ReplayMessage closes its queue with the last message: that one is usually lost
    assert len(frames) >= len(rec.frames) - 2
    for f in frames:
        src = rec.frames[f.frame_number]
        assert np.array_equal(f.depth, src.depth) and f.depth.dtype == np.uint16   # RAW16 bit-exact
        assert np.array_equal(f.color, src.color)
        assert f.intrinsics == rec.camera and f.depth_units == 0.001
        assert f.distortion == pytest.approx(DEPTHAI_LENS, abs=1e-7)      # the lens, as float32 in the recording
        assert f.sensor_time == pytest.approx(src.time, abs=1e-6)


def test_one_file_of_the_recording_is_enough_to_name_it(depthai_recording):
    with DepthAIDriver(CameraSettings(file=str(rec_file := depthai_recording.path / "depth.mcap"))) as d:
        assert d.read(3.0) is not None and "color.mcap" in d.device.details["files"]
    assert rec_file.exists()


def test_no_device_is_found_quickly_and_reported_cleanly(tmp_path):
    assert DepthAIDriver.list_devices() == []
    with pytest.raises(NoDevice, match="no DepthAI"):
        DepthAIDriver(CameraSettings(search_timeout=0.5)).open()
    (tmp_path / "only.mcap").write_bytes(b"")
    with pytest.raises(NoDevice, match="needs a depth and a colour"):
        DepthAIDriver(CameraSettings(file=str(tmp_path))).open()


def test_the_live_pipeline_uses_api_this_depthai_has():
    """No device here to build the live pipeline on; at least every name it uses exists."""
    from raspv_camera import sdk_imports
    dai = sdk_imports.depthai()
    for owner, names in ((dai.node.Camera, ("build", "requestOutput")),
                         (dai.node.StereoDepth, ("setDepthAlign", "setOutputSize", "setLeftRightCheck")),
                         (dai.node.Sync, ("setSyncThreshold",)), (dai.node.IMU, ("enableIMUSensor", "setBatchReportThreshold",
                                                                                  "setMaxBatchReports")),
                         (dai.Device, ("getAllAvailableDevices", "getConnectedIMU", "readCalibration", "getPlatform",
                                       "isClosed", "getUsbSpeed", "getDeviceName", "getDeviceId")),
                         (dai.CalibrationHandler, ("getImuToCameraExtrinsics", "getCameraIntrinsics")),
                         (dai.MessageQueue, ("get", "tryGetAll"))):
        for name in names:
            assert hasattr(owner, name), f"{owner.__name__}.{name}"
    assert hasattr(dai.IMUSensor, "ACCELEROMETER_CALIBRATED") and hasattr(dai.Platform, "RVC4")
    assert hasattr(dai.node, "ImageAlign") and hasattr(dai.CameraBoardSocket, "CAM_C")


def test_the_imu_rotation_is_read_from_the_calibration_or_refused_in_one_line():
    """A device calibration (depthai's own CalibrationHandler, built on the host): its IMU → CAM_A
    rotation is used as it is; without one the IMU is refused, never taken as the identity."""
    from raspv_camera import sdk_imports
    dai = sdk_imports.depthai()
    calibration = dai.CalibrationHandler()
    calibration.setCameraIntrinsics(dai.CameraBoardSocket.CAM_A, [[500, 0, 320], [0, 500, 200], [0, 0, 1]], 640, 400)
    with pytest.raises(ImuCalibrationError, match="no IMU-to-camera rotation") as info:
        imu_to_camera_rotation(calibration, dai)
    assert "\n" not in str(info.value)
    turned = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]                     # IMU x → camera y (a quarter turn)
    calibration.setImuExtrinsics(dai.CameraBoardSocket.CAM_A, turned, [0, 0, 0], [0, 0, 0])
    assert np.array_equal(imu_to_camera_rotation(calibration, dai), np.array(turned, float))
