"""Carrying a scene result into a later depth frame (raspv_perception.scene_carry): a synthetic
walk with true poses, real Kinect frames with RGB-D odometry, floor that something steps onto,
and the floor frame's contents staying put in the world."""

import numpy as np
import pytest

from raspv_camera.synthetic_scene import SyntheticRoom, camera_rotation
from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception import scene_labels as L
from raspv_perception.rgbd_odometry import RGBDOdometry
from raspv_perception.scene_carry import carry_labels, structure_seen_from
from raspv_perception.scene_perception import ScenePerception

K = CameraIntrinsics.from_hfov(640, 480, 60.0)
STRIDE = 4


def agreement(a, b):
    """Share of pixels labelled in ``b`` where ``a`` says the same."""
    m = b != L.NONE
    return float((a[m] == b[m]).mean())


@pytest.fixture(scope="module")
def walk():
    """Scene results of a walk in the synthetic room at 30 Hz: [(W ← C, depth, result)]."""
    room, scene = SyntheticRoom(K), ScenePerception()
    out = []
    for t in np.arange(0.0, 2.0, 1 / 30):
        T = room.pose_at(t)
        depth = room.render(T)[1]
        out.append((T, depth, scene.process(depth, K)))
    return out


def carried_pair(old, new):
    (T0, _, r0), (T1, d1, _) = old, new
    new_from_old = np.linalg.inv(T1) @ T0
    s = structure_seen_from(r0.structure, new_from_old)
    return s, carry_labels(r0.labels, d1, K, new_from_old, s.floor_plane)


def not_moved(old, new):
    """A broken carry: the old labels through the new depth's checks with no motion."""
    (_, _, r0), (_, d1, _) = old, new
    return carry_labels(r0.labels, d1, K, np.eye(4), structure_seen_from(r0.structure, np.eye(4)).floor_plane)


def test_a_walk_carried_one_frame_matches_the_next_frames_own_result(walk):
    ours, same_pixels = [], []
    for old, new in zip(walk[:-1:3], walk[1::3]):
        s, labels = carried_pair(old, new)
        own = new[2]
        truth = own.labels[::STRIDE, ::STRIDE]
        ours.append(agreement(labels, truth))
        same_pixels.append(agreement(old[2].labels[::STRIDE, ::STRIDE], truth))
        assert s.floor_found
        np.testing.assert_allclose(s.floor_plane, own.structure.floor_plane, atol=0.005)
        np.testing.assert_allclose(s.camera_to_floor, own.structure.camera_to_floor, atol=0.005)
        assert s.camera_pitch_deg == pytest.approx(own.structure.camera_pitch_deg, abs=0.3)
    # measured: 99.1 % on average, 97.6 % at worst; the old labels as they were: 99.0 %. One frame
    # (2 cm) apart the labels barely move, so this checks the carried structure and that carrying
    # loses nothing; the five-frame test below tells carrying from not carrying.
    assert np.mean(ours) >= 0.97 and min(ours) >= 0.95
    assert np.mean(ours) >= np.mean(same_pixels)


def test_a_walk_carried_five_frames_still_matches(walk):
    """Carried 167 ms (five frames of 30 Hz, 6.7 cm and 2.4° of walk): what the display shows
    when scene perception falls behind."""
    ours, same_pixels, unmoved = [], [], []
    for old, new in zip(walk[:-5:5], walk[5::5]):
        _, labels = carried_pair(old, new)
        truth = new[2].labels[::STRIDE, ::STRIDE]
        ours.append(agreement(labels, truth))
        same_pixels.append(agreement(old[2].labels[::STRIDE, ::STRIDE], truth))
        unmoved.append(agreement(not_moved(old, new), truth))
    # measured: 98.4 % carried, 95.8 % the old labels as they were, 96.3 % carried without the
    # motion (a broken carry: the depth checks alone). Errors: 1.6 % vs 4.2 % and 3.7 %. Carrying
    # must remove at least 40 % of the errors of either; a carry that ignores the motion removes 12 %.
    errors = 1 - np.mean(ours)
    assert np.mean(ours) >= 0.96
    assert errors <= 0.6 * (1 - np.mean(same_pixels)) and errors <= 0.6 * (1 - np.mean(unmoved))


def test_floor_frame_contents_stay_put_in_the_world(walk):
    (T0, _, r0), (T1, _, _) = walk[0], walk[6]
    s = structure_seen_from(r0.structure, np.linalg.inv(T1) @ T0)
    assert len(r0.structure.free_floor) > 3 and r0.structure.obstacles

    def world(T, camera_to_floor, xz):
        p = np.column_stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1], np.ones(len(xz))])
        return (T @ camera_to_floor @ p.T).T[:, :3]
    np.testing.assert_allclose(world(T1, s.camera_to_floor, s.free_floor),
                               world(T0, r0.structure.camera_to_floor, r0.structure.free_floor), atol=1e-9)
    for a, b in zip(s.obstacles, r0.structure.obstacles):
        np.testing.assert_allclose((T1 @ np.append(a.centroid, 1))[:3], (T0 @ np.append(b.centroid, 1))[:3], atol=1e-9)
        assert np.all(a.max_floor - a.min_floor >= b.max_floor - b.min_floor - 1e-9)   # a turned box only grows
    for a, b in zip(s.planes, r0.structure.planes):       # the same points on the same plane
        assert a.coefficients @ np.append(a.centroid, 1) == pytest.approx(b.coefficients @ np.append(b.centroid, 1),
                                                                         abs=1e-9)


def test_floor_stepped_on_becomes_obstacle_and_floor_into_view_becomes_floor(walk):
    T, depth, r = walk[0]
    s = r.structure
    labels = r.labels.copy()
    floor = labels == L.FLOOR
    assert floor.mean() > 0.15
    # something steps onto the floor at the bottom right of the image
    stepped = depth.copy()
    rows, cols = slice(400, 480), slice(400, 560)
    assert floor[rows, cols].all()
    stepped[rows, cols] *= 0.8                               # nearer: points rise above the floor
    # and the old frame did not see the floor at the bottom-left corner (no reading there)
    labels[400:, 160:320] = L.NONE
    out = carry_labels(labels, stepped, K, np.eye(4), s.floor_plane)
    block = out[rows.start // STRIDE:rows.stop // STRIDE, cols.start // STRIDE:cols.stop // STRIDE]
    assert (block == L.OBSTACLE).mean() > 0.95
    assert (out[400 // STRIDE:, 160 // STRIDE:320 // STRIDE] == L.FLOOR).all()
    # elsewhere the same frame carried by no motion is its labels on the grid
    same = carry_labels(r.labels, depth, K, np.eye(4), s.floor_plane)
    assert agreement(same, r.labels[::STRIDE, ::STRIDE]) > 0.999


def test_no_depth_is_no_label_and_no_floor_skips_the_floor_check(walk):
    _, depth, r = walk[0]
    holes = depth.copy()
    holes[:, :320] = np.nan
    out = carry_labels(r.labels, holes, K, np.eye(4), None)
    assert (out[:, :320 // STRIDE] == L.NONE).all()
    assert (out[:, 320 // STRIDE:] == r.labels[::STRIDE, 320::STRIDE]).all()


def test_real_kinect_frames_carried_by_odometry_match_their_own_result(kinect_frames):
    """The PCL table frames (0.25 s apart, hand-held): frame 0's result carried into frame 1
    with the RGB-D odometry's motion, against frame 1's own."""
    scene, odometry = ScenePerception(), RGBDOdometry()
    results, motion = [], []
    for rgb, depth, K_ in kinect_frames[:2]:
        results.append(scene.process(depth, K_))
        motion.append(odometry.process(rgb, depth, K_).relative)
    depth1, K_ = kinect_frames[1][1], kinect_frames[1][2]
    new_from_old = np.linalg.inv(motion[1])
    s = structure_seen_from(results[0].structure, new_from_old)
    plane = s.floor_plane if s.floor_found else None
    carried = carry_labels(results[0].labels, depth1, K_, new_from_old, plane)
    truth = results[1].labels[::STRIDE, ::STRIDE]
    ours, same = agreement(carried, truth), agreement(results[0].labels[::STRIDE, ::STRIDE], truth)
    s0 = structure_seen_from(results[0].structure, np.eye(4))
    unmoved = agreement(carry_labels(results[0].labels, depth1, K_, np.eye(4),
                                     s0.floor_plane if s0.floor_found else None), truth)
    print(f"kinect: carried {ours:.3f}, same pixels {same:.3f}, carried without the motion {unmoved:.3f}, "
          f"motion {np.linalg.norm(new_from_old[:3, 3]):.3f} m")
    # measured: 97.1 %; the old labels as they were 95.4 %, carried without the motion 95.5 % (errors
    # 2.9 % vs 4.6 % and 4.5 %): at least a fifth of the errors removed, which a broken carry does not
    assert ours >= 0.95
    assert 1 - ours <= 0.8 * (1 - same) and 1 - ours <= 0.8 * (1 - unmoved)


def test_a_head_turned_back_takes_the_labels_of_the_view_seen_before():
    """A 40° head turn from the synthetic room's 0° view: what the 0° result did not see takes
    the labels of a frame remembered looking ~40° (``earlier``), not labels continued from the
    neighbours (what the spv node carries when the wearer looks back and forth)."""
    room, scene = SyntheticRoom(K), ScenePerception()
    start = room.pose_at(0.0)

    def view(yaw_deg):
        T = start.copy()
        T[:3, :3] = camera_rotation(np.pi / 2 + np.radians(yaw_deg), np.radians(room.pitch_down_deg))
        depth = room.render(T)[1]
        return T, depth, scene.process(depth, K)

    (T0, _, r0), (T40, d40, r40), (T38, _, r38) = view(0.0), view(40.0), view(38.0)
    s = structure_seen_from(r0.structure, np.linalg.inv(T40) @ T0)
    continued = carry_labels(r0.labels, d40, K, np.linalg.inv(T40) @ T0, s.floor_plane)
    remembered = carry_labels(r0.labels, d40, K, np.linalg.inv(T40) @ T0, s.floor_plane,
                              earlier=[(r38.labels, np.linalg.inv(T40) @ T38)])
    truth = r40.labels[::STRIDE, ::STRIDE]
    ours, theirs = agreement(remembered, truth), agreement(continued, truth)
    print(f"40° turn: with the remembered view {ours:.3f}, continued {theirs:.3f}")
    # measured: 97.9 % with the remembered view, 84.1 % continued (errors 2.1 % vs 15.9 %)
    assert ours >= 0.96 and 1 - ours <= 0.5 * (1 - theirs)
    # nothing remembered that saw it: the same as before
    far = view(-60.0)
    assert (carry_labels(r0.labels, d40, K, np.linalg.inv(T40) @ T0, s.floor_plane,
                         earlier=[(far[2].labels, np.linalg.inv(T40) @ far[0])]) == continued).mean() > 0.99
