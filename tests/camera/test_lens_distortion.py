"""The lens distortion the SDKs report, passed on as OpenCV coefficients: checked against the
SDK's own projection functions (librealsense's rs2_project_point_to_pixel /
rs2_deproject_pixel_to_point) through OpenCV's projectPoints / undistortPoints."""
import cv2
import numpy as np
import pytest

from raspv_camera import lens_distortion
from raspv_camera.camera_driver import CameraSettings
from raspv_camera.realsense_driver import RealSenseDriver
from raspv_camera.sdk_recordings import write_realsense_recording
from raspv_common.intrinsics import CameraIntrinsics

from .conftest import pattern_frames

K = CameraIntrinsics(640, 480, 615.0, 614.0, 322.0, 241.0)      # a D435's colour camera at 640x480
# a D435's colour lens as its calibration reports it (inverse Brown–Conrady, magnitudes of real units)
D400_COLOUR = [0.12, -0.25, 0.0012, -0.0008, 0.10]


def _rs_intrinsics(rs, model: str, coeffs):
    i = rs.intrinsics()
    i.width, i.height, i.fx, i.fy, i.ppx, i.ppy = K.width, K.height, K.fx, K.fy, K.cx, K.cy
    i.model, i.coeffs = getattr(rs.distortion, model), list(coeffs)
    return i


def _sdk_projection(rs, intr):
    return lambda points: [rs.rs2_project_point_to_pixel(intr, [float(v) for v in p]) for p in points]


def _pixels():
    u, v = np.meshgrid(np.linspace(5, K.width - 6, 17), np.linspace(5, K.height - 6, 13))
    return np.stack([u.ravel(), v.ravel()], axis=1)


def _opencv_undistorted(pixels, coefficients):
    """Normalised undistorted points of distorted ``pixels`` with OpenCV."""
    out = cv2.undistortPoints(pixels.reshape(-1, 1, 2).astype(np.float64), K.K, np.array(coefficients),
                              criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12))
    return out.reshape(-1, 2)


@pytest.mark.parametrize("model", ["brown_conrady", "modified_brown_conrady", "inverse_brown_conrady"])
def test_opencv_coefficients_project_as_librealsense_does(model):
    rs = pytest.importorskip("pyrealsense2")
    intr = _rs_intrinsics(rs, model, D400_COLOUR)
    coefficients, residual = lens_distortion.from_realsense(model, D400_COLOUR, K, _sdk_projection(rs, intr))
    assert residual < 0.05 and (model != "brown_conrady" or coefficients == tuple(D400_COLOUR))
    points = np.column_stack([_opencv_undistorted(_pixels(), [0] * 5), np.ones(len(_pixels()))]) * 2.0
    sdk = np.array([rs.rs2_project_point_to_pixel(intr, list(p)) for p in points])
    ours = cv2.projectPoints(points, np.zeros(3), np.zeros(3), K.K, np.array(coefficients))[0].reshape(-1, 2)
    assert np.abs(ours - sdk).max() < 0.05


def test_inverse_brown_conrady_undistorts_as_librealsense_deprojects():
    """D400 colour streams: the fitted OpenCV coefficients give the same rays for the same
    pixels as the SDK's deprojection (to a fraction of a pixel)."""
    rs = pytest.importorskip("pyrealsense2")
    intr = _rs_intrinsics(rs, "inverse_brown_conrady", D400_COLOUR)
    coefficients, residual = lens_distortion.from_realsense("inverse_brown_conrady", D400_COLOUR, K,
                                                            _sdk_projection(rs, intr))
    assert residual < lens_distortion.FIT_TOLERANCE_PX
    pixels = _pixels()
    sdk = np.array([rs.rs2_deproject_pixel_to_point(intr, list(p), 1.0)[:2] for p in pixels])
    ours = _opencv_undistorted(pixels, coefficients)
    assert np.abs((ours - sdk) * K.fx).max() < 0.5
    # what publishing the camera as rectified got wrong (5.6 px at the corners)
    assert np.abs((_opencv_undistorted(pixels, [0.0] * 5) - sdk) * K.fx).max() > 3


def test_no_distortion_fisheye_and_depthai_models():
    def unused(points):
        raise AssertionError("no projection needed")
    assert lens_distortion.from_realsense("none", [0.1] * 5, K, unused) == ((), 0.0)
    assert lens_distortion.from_realsense("inverse_brown_conrady", [0.0] * 5, K, unused) == ((), 0.0)
    with pytest.raises(lens_distortion.UnsupportedDistortion, match="fisheye"):
        lens_distortion.from_realsense("kannala_brandt4", [0.1, 0.0, 0.0, 0.0, 0.0], K, unused)
    assert lens_distortion.from_depthai("Perspective", []) == ()
    assert lens_distortion.from_depthai("Perspective", [0.1, -0.2, 0.001, 0.002, 0.05] + [0.0] * 9) == \
        (0.1, -0.2, 0.001, 0.002, 0.05)
    eight = [0.1, -0.2, 0.001, 0.002, 0.05, 0.01, 0.02, 0.03]
    assert lens_distortion.from_depthai("Perspective", eight + [0.0] * 6) == tuple(eight)
    with pytest.raises(lens_distortion.UnsupportedDistortion, match="thin-prism"):
        lens_distortion.from_depthai("Perspective", eight + [0.001] + [0.0] * 5)
    with pytest.raises(lens_distortion.UnsupportedDistortion, match="Fisheye"):
        lens_distortion.from_depthai("Fisheye", [0.1, 0.0, 0.0, 0.0])


def test_a_realsense_recording_hands_its_colour_lens_to_the_frames(tmp_path):
    rs = pytest.importorskip("pyrealsense2")
    small = K.scaled(160, 120)
    path = write_realsense_recording(tmp_path / "lens.db3", pattern_frames(5), small,
                                     color_lens=("inverse_brown_conrady", D400_COLOUR))
    with RealSenseDriver(CameraSettings(file=str(path))) as driver:
        frame = None
        while frame is None:
            frame = driver.read(5.0)
    intr = _rs_intrinsics(rs, "inverse_brown_conrady", D400_COLOUR)
    intr.width, intr.height, intr.fx, intr.fy, intr.ppx, intr.ppy = small.width, small.height, small.fx, small.fy, \
        small.cx, small.cy
    expected, _ = lens_distortion.from_realsense("inverse_brown_conrady", D400_COLOUR, small, _sdk_projection(rs, intr))
    assert len(frame.distortion) == 5 and frame.distortion == pytest.approx(expected, abs=1e-4)
