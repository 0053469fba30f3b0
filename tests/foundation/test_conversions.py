import numpy as np
import pytest
from geometry_msgs.msg import Pose
from sensor_msgs.msg import Image

from raspv_common.conversions import (ImageEncodingError, array_to_image, camera_info_distortion,
                                      camera_info_to_intrinsics, depth_from_image, image_to_array,
                                      intrinsics_to_camera_info, matrix_to_pose, pose_to_matrix, rgb_from_image,
                                      seconds_to_stamp, stamp_to_seconds)
from raspv_common.intrinsics import CameraIntrinsics


@pytest.mark.parametrize("enc,shape,dtype", [("rgb8", (5, 7, 3), np.uint8), ("mono8", (5, 7), np.uint8),
                                             ("16UC1", (5, 7), np.uint16), ("32FC1", (5, 7), np.float32),
                                             ("bgra8", (5, 7, 4), np.uint8)])
def test_image_round_trip_is_exact_and_zero_copy(enc, shape, dtype):
    a = (np.random.default_rng(1).random(shape) * 200).astype(dtype)
    msg = array_to_image(a, enc)
    b = image_to_array(msg)
    np.testing.assert_array_equal(a, b)
    assert np.shares_memory(b, np.frombuffer(msg.data, dtype=np.uint8))
    assert not b.flags.writeable


def test_padded_rows_and_big_endian():
    a = np.arange(12, dtype=np.uint16).reshape(3, 4)
    msg = Image(height=3, width=4, encoding="16UC1", is_bigendian=1, step=10)
    padded = np.zeros((3, 10), dtype=np.uint8)
    padded[:, :8] = a.astype(">u2").view(np.uint8).reshape(3, 8)
    msg.data = padded.tobytes()
    np.testing.assert_array_equal(image_to_array(msg), a)


@pytest.mark.parametrize("msg,fragment", [
    (Image(height=2, width=2, encoding="yuv422", step=4, data=bytes(8)), "unsupported image encoding 'yuv422'"),
    (Image(height=2, width=2, encoding="rgb8", step=6, data=bytes(5)), "5 data bytes, expected 12"),
    (Image(height=2, width=2, encoding="rgb8", step=3, data=bytes(12)), "step 3 is smaller than a row"),
    (Image(height=0, width=2, encoding="mono8", step=2, data=b""), "empty"),
])
def test_malformed_images_get_clear_errors(msg, fragment):
    with pytest.raises(ImageEncodingError, match=fragment):
        image_to_array(msg)


def test_depth_units_and_invalid_readings():
    mm = np.array([[0, 1500], [65535, 2]], dtype=np.uint16)
    d = depth_from_image(array_to_image(mm, "16UC1"))
    assert np.isnan(d[0, 0]) and d[0, 1] == pytest.approx(1.5) and d[1, 0] == pytest.approx(65.535)
    m = np.array([[np.nan, np.inf], [-1.0, 2.0]], dtype=np.float32)
    d = depth_from_image(array_to_image(m, "32FC1"))
    assert np.isnan(d[0]).all() and np.isnan(d[1, 0]) and d[1, 1] == 2.0
    with pytest.raises(ImageEncodingError, match="expected a depth image"):
        depth_from_image(array_to_image(np.zeros((2, 2, 3), np.uint8), "rgb8"))


def test_colour_encodings_become_rgb():
    rgb = np.zeros((2, 2, 3), np.uint8)
    rgb[..., 0] = 200
    assert (rgb_from_image(array_to_image(rgb[..., ::-1], "bgr8"))[..., 0] == 200).all()
    with pytest.raises(ImageEncodingError, match="colour image"):
        rgb_from_image(array_to_image(np.zeros((2, 2), np.float32), "32FC1"))


def test_camera_info_round_trip_and_invalid():
    intr = CameraIntrinsics(640, 480, 525.0, 524.0, 319.5, 239.5)
    assert camera_info_to_intrinsics(intrinsics_to_camera_info(intr)) == intr
    with pytest.raises(ValueError, match="no valid calibration"):
        camera_info_to_intrinsics(intrinsics_to_camera_info(intr).__class__())


def test_camera_info_carries_the_lens_distortion():
    intr = CameraIntrinsics(640, 480, 517.3, 516.5, 318.6, 255.3)
    assert camera_info_distortion(intrinsics_to_camera_info(intr)) == ()          # rectified: zeros
    tum = (0.2624, -0.9531, -0.0054, 0.0026, 1.1633)
    msg = intrinsics_to_camera_info(intr, distortion=tum)
    assert msg.distortion_model == "plumb_bob" and camera_info_distortion(msg) == pytest.approx(tum)
    assert camera_info_distortion(intrinsics_to_camera_info(intr, distortion=tum[:4])) == pytest.approx(tum[:4] + (0,))
    rational = intrinsics_to_camera_info(intr, distortion=tum + (0.1, 0.2, 0.3))
    assert rational.distortion_model == "rational_polynomial" and len(camera_info_distortion(rational)) == 8
    msg.distortion_model = "equidistant"
    with pytest.raises(ValueError, match="'equidistant' is not supported"):
        camera_info_distortion(msg)
    msg.distortion_model, msg.d = "plumb_bob", [0.1, 0.2, 0.3]
    with pytest.raises(ValueError, match="4, 5 or 8"):
        camera_info_distortion(msg)


def test_pose_matrix_round_trip():
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        pose = Pose()
        pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = q
        pose.position.x, pose.position.y, pose.position.z = rng.normal(size=3)
        T = pose_to_matrix(pose)
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(pose_to_matrix(matrix_to_pose(T)), T, atol=1e-12)


def test_stamps():
    assert stamp_to_seconds(seconds_to_stamp(1234.5678)) == pytest.approx(1234.5678, abs=1e-9)
    assert seconds_to_stamp(1.9999999999).sec == 2
