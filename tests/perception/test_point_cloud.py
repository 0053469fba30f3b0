"""Organised cloud, normals and voxel grid on analytic depth."""
import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception.point_cloud import (DepthInputError, organised_cloud, organised_normals, voxel_downsample)

from .conftest import plane_depth

K = CameraIntrinsics.from_hfov(160, 120, 60.0)


def test_invalid_and_out_of_range_depth_become_nan():
    depth = np.full((120, 160), 2.0, dtype=np.float32)
    depth[0, :4] = [np.nan, 0.0, np.inf, -1.0]
    depth[1, 0] = 0.1     # nearer than min_depth
    depth[1, 1] = 9.0     # beyond max_depth
    cloud = organised_cloud(depth, K, stride=1, min_depth=0.2, max_depth=8.0)
    assert not cloud.valid[0, :4].any() and not cloud.valid[1, :2].any()
    assert np.isnan(cloud.points[0, :4]).all()
    assert cloud.valid.sum() == 160 * 120 - 6
    full = K.backproject(depth)
    np.testing.assert_allclose(cloud.points[5, 7], full[5, 7], rtol=1e-6)


def test_stride_samples_every_nth_pixel_and_upsamples_back():
    depth = np.random.default_rng(0).uniform(1, 3, (120, 160)).astype(np.float32)
    cloud = organised_cloud(depth, K, stride=4)
    assert cloud.shape == (30, 40)
    np.testing.assert_allclose(cloud.points[3, 5], K.backproject(depth)[12, 20], rtol=1e-6)
    ids = np.arange(30 * 40).reshape(30, 40)
    full = cloud.upsample(ids)
    assert full.shape == (120, 160) and full[13, 23] == ids[3, 5]
    # footprint: a sample at depth z stands for (stride·z/f)² m²
    assert cloud.footprint[3, 5] == pytest.approx((4 * depth[12, 20] / K.fx) ** 2, rel=1e-5)


def test_millimetre_depth_is_accepted():
    mm = np.full((120, 160), 1500, dtype=np.uint16)
    mm[0, 0] = 0
    cloud = organised_cloud(mm, K, stride=1)
    assert cloud.points[10, 10, 2] == pytest.approx(1.5)
    assert not cloud.valid[0, 0]


@pytest.mark.parametrize("bad, message", [
    (np.zeros((100, 160), np.float32), "100 but the camera model is 160x120"),
    (np.zeros((120, 160, 3), np.float32), "single-channel"),
    (np.zeros((120, 160), np.int32), "float metres or uint16"),
    ([[1.0]], "numpy array"),
])
def test_bad_depth_is_refused_with_a_reason(bad, message):
    with pytest.raises(DepthInputError, match=message.split(" but")[0] if "camera" in message else message):
        organised_cloud(bad, K)


def test_normals_of_a_tilted_plane_point_to_the_camera():
    n = np.array([0.2, -0.9, -0.3])
    n /= np.linalg.norm(n)
    depth = plane_depth(K, n, 1.5)
    cloud = organised_cloud(depth, K, stride=1, max_depth=20.0)
    normals, ok = organised_normals(cloud, step=2)
    assert ok[cloud.valid].mean() > 0.9 and not ok[~cloud.valid].any()
    angles = np.degrees(np.arccos(np.clip(normals[ok] @ n, -1, 1)))
    assert angles.max() < 0.5


def test_normals_are_not_trusted_across_a_depth_jump():
    depth = np.full((120, 160), 2.0, dtype=np.float32)
    depth[:, 80:] = 3.0
    cloud = organised_cloud(depth, K, stride=1)
    normals, ok = organised_normals(cloud, step=2)
    assert not ok[:, 77:83].any()
    assert ok[3:-3, 10:70].all() and ok[3:-3, 90:150].all()
    np.testing.assert_allclose(normals[60, 40], [0, 0, -1], atol=1e-5)


def test_voxel_grid_groups_points_and_maps_back():
    pts = np.array([[0.01, 0.01, 0.01], [0.02, 0.03, 0.04], [0.11, 0.0, 0.0], [0.12, 0.01, 0.0]], np.float32)
    grid = voxel_downsample(pts, 0.05)
    assert len(grid.counts) == 2 and grid.counts.sum() == 4
    assert grid.inverse[0] == grid.inverse[1] != grid.inverse[2] == grid.inverse[3]
    np.testing.assert_allclose(grid.centroids[grid.inverse[0]], [0.015, 0.02, 0.025], atol=1e-6)
    with pytest.raises(ValueError, match="positive"):
        voxel_downsample(pts, 0.0)
