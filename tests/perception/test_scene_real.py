"""Scene perception on real sensor frames (tests/data/rgbd, see its README).

Expected values were measured by hand: least-squares planes through image regions that are
visibly floor (or table) in the colour image, after dropping 3-σ outliers:
- TUM desk frame: floor patches give camera height 1.74–1.83 m, pitch 27–30.5° down, roll
  −1.2…0.1°; the desk top lies 0.72–0.75 m above that floor.
- NYU basement frame: floor patches give 1.55–1.61 m, pitch 14–17°, roll −2.7…4.1°.
- PCL Kinect frames: the carpet under the laptop and the box is a plane 0.715–0.731 m from the
  camera with its normal 46° from the camera's −y axis; the floor beyond it is the same plane
  (1.6 cm apart), so it is a floor-level surface seen from 0.72 m looking 46° down — outside
  the first-floor limits (camera 1.0–2.0 m, ≤ 40°): "no floor", the surface is the dominant
  horizontal (support) plane. The laptop (lid up to 0.22 m) and the box (0.085 m high) stand on
  it 4.3 cm apart.
"""
import math

import numpy as np
import pytest

from raspv_perception import scene_labels as L
from raspv_perception.floor import angle_deg
from raspv_perception.scene_perception import ScenePerception
from raspv_perception.scene_structure import GravitySource, PlaneType

LAPTOP_PIXELS = (slice(150, 315), slice(135, 370))   # rows, cols of the laptop in the colour image
BOX_PIXELS = (slice(185, 310), slice(380, 500))



@pytest.fixture(scope="module")
def tum(tum_frame):
    _, depth, K = tum_frame
    return ScenePerception().process(depth, K)


@pytest.fixture(scope="module")
def nyu(nyu_frame):
    _, depth, K = nyu_frame
    return ScenePerception().process(depth, K)


@pytest.fixture(scope="module")
def kinect(kinect_frames):
    perception = ScenePerception()
    return [perception.process(depth, K) for _, depth, K in kinect_frames]


def test_tum_floor_height_and_tilt(tum):
    s = tum.structure
    assert s.floor_found and s.gravity_source == GravitySource.FLOOR
    assert s.camera_height == pytest.approx(1.79, abs=0.08)
    assert s.camera_pitch_deg == pytest.approx(29.0, abs=3.0)
    assert abs(s.camera_roll_deg) < 3.0


def test_tum_desk_is_a_horizontal_plane_and_an_obstacle(tum):
    s = tum.structure
    desk = [p for p in s.planes_of(PlaneType.HORIZONTAL) if abs(p.height - 0.735) < 0.06]
    assert desk and desk[0].area > 0.5
    # the desk (with everything on it) is the biggest obstacle, 1.3–1.8 m ahead
    biggest = max(s.obstacles, key=lambda o: o.num_points)
    assert 1.3 < biggest.distance < 2.0
    # the floor at the bottom is floor, free except around the chairs' wheels; the desk is not floor
    bottom = tum.labels[420:460, 280:560]
    assert np.isin(bottom, [L.FLOOR, L.FLOOR_BLOCKED]).mean() > 0.95 and (bottom == L.FLOOR).mean() > 0.5
    assert not np.isin(tum.labels[205:225, 60:280], [L.FLOOR, L.FLOOR_BLOCKED]).any()


def test_nyu_floor_height_and_tilt(nyu):
    s = nyu.structure
    assert s.floor_found
    assert s.camera_height == pytest.approx(1.58, abs=0.06)
    assert s.camera_pitch_deg == pytest.approx(15.5, abs=2.5)
    assert -3.0 < s.camera_roll_deg < 5.0
    assert (nyu.labels[430:475, 400:600] == L.FLOOR).mean() > 0.8
    assert s.manhattan_found and len(s.planes_of(PlaneType.WALL)) >= 2


def test_kinect_table_has_no_floor_but_a_dominant_horizontal_plane(kinect):
    for result in kinect:
        s = result.structure
        assert not s.floor_found and math.isnan(s.camera_height) and len(s.free_floor) == 0
        assert s.gravity_source == GravitySource.SUPPORT
        top = s.planes_of(PlaneType.HORIZONTAL)[0]
        assert top.area > 1.0 and all(top.area > p.area for p in s.planes if p is not top)
        assert top.coefficients[3] == pytest.approx(0.72, abs=0.02)
        assert angle_deg(top.coefficients[:3], [0, -1, 0]) == pytest.approx(46.0, abs=2.0)
        assert (result.labels[380:470, 40:600] == L.HORIZONTAL).mean() > 0.9


def test_kinect_laptop_and_box_are_separate_obstacles_on_it(kinect, kinect_frames):
    K = kinect_frames[0][2]
    for result in kinect:
        found = {}
        for o in result.structure.obstacles:
            u, v, _ = K.project(o.centroid)
            for name, (rows, cols) in (("laptop", LAPTOP_PIXELS), ("box", BOX_PIXELS)):
                if rows.start <= v[0] < rows.stop and cols.start <= u[0] < cols.stop:
                    assert name not in found, f"two clusters for the {name}"
                    found[name] = o
        assert set(found) == {"laptop", "box"}
        assert found["laptop"].height == pytest.approx(0.22, abs=0.04)
        assert found["box"].height == pytest.approx(0.085, abs=0.03)
        assert found["laptop"].num_points > found["box"].num_points
        labels = result.labels
        assert (labels[LAPTOP_PIXELS][30:-30, 30:-30] == L.OBSTACLE).mean() > 0.8
        assert (labels[BOX_PIXELS][30:-30, 20:-20] == L.OBSTACLE).mean() > 0.8
