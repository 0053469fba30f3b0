import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.rgbd_files import RGBDFormatError, read_color, read_depth_scaled, read_nyu_disparity


def test_paper_camera_focal_length():
    intr = CameraIntrinsics.from_hfov(640, 480, 60.0)
    assert intr.fx == pytest.approx(554.26, abs=0.01)
    assert (intr.cx, intr.cy) == (319.5, 239.5)
    assert intr.hfov_deg == pytest.approx(60.0)


def test_project_backproject_agree():
    intr = CameraIntrinsics(64, 48, 50.0, 52.0, 31.5, 23.5)
    depth = np.full((48, 64), 2.0, np.float32)
    depth[0, 0] = np.nan
    pts = intr.backproject(depth)
    assert np.isnan(pts[0, 0]).all()
    u, v, z = intr.project(pts[10:12, 20:23].reshape(-1, 3))
    np.testing.assert_allclose(u, np.tile([20, 21, 22], 2), atol=1e-4)
    np.testing.assert_allclose(v, np.repeat([10, 11], 3), atol=1e-4)
    np.testing.assert_allclose(intr.scaled(128, 96).cx, 63.5)


def test_a_margin_extends_the_field_at_the_same_focal_length():
    intr = CameraIntrinsics.from_hfov(320, 240, 60.0)
    wide = intr.with_margin(10.0)
    assert (wide.width, wide.height) == (465, 366)          # 2·f·tan(30° + 10°), 2·f·tan(23.4° + 10°)
    assert (wide.fx, wide.fy) == (intr.fx, intr.fy) and (wide.cx, wide.cy) == (232.0, 182.5)
    assert wide.hfov_deg == pytest.approx(80.0, abs=0.1)
    assert intr.with_margin(0.0) == intr
    for bad in (-1.0, float("nan"), 60.0):
        with pytest.raises(ValueError):
            intr.with_margin(bad)


def test_invalid_intrinsics_rejected():
    with pytest.raises(ValueError):
        CameraIntrinsics(0, 10, 1, 1, 0, 0)
    with pytest.raises(ValueError):
        CameraIntrinsics(10, 10, float("nan"), 1, 0, 0)


def test_real_frames_decode_to_plausible_metres(data_dir):
    rgbd = data_dir / "rgbd"
    nyu = read_nyu_disparity(rgbd / "nyu_depth.pgm")
    assert 3.0 < np.nanmedian(nyu) < 3.6                    # provenance note: median ≈ 3.3 m
    tum = read_depth_scaled(rgbd / "tum_depth.png", 1 / 5000)
    assert 1.0 < np.nanmedian(tum) < 4.0
    table = read_depth_scaled(next((rgbd / "kinect_table").glob("*_depth.tiff")), 0.001)
    assert 0.5 < np.nanmedian(table) < 2.0
    assert read_color(rgbd / "tum_color.png").shape == (480, 640, 3)


def test_unreadable_files_raise_clear_errors(tmp_path):
    bad = tmp_path / "x.png"
    bad.write_bytes(b"not an image")
    with pytest.raises(RGBDFormatError, match="not a readable"):
        read_color(bad)
    with pytest.raises(RGBDFormatError, match="not a readable depth image"):
        read_depth_scaled(bad, 0.001)
