"""Display-time reprojection (raspv_spv.reprojection, Sampling.turned) and simulated device latency."""
import math

import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.rotations import quaternion_to_matrix
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.projected_lines import phosphenes_on_lines
from raspv_spv.phosphene_map import PhospheneMap
from raspv_spv.reprojection import (OPTICAL_IN_HEAD, DisplayFrame, DisplayView, FrameHistory, ViewTracker,
                                    rotation_angle_deg)
from raspv_spv.sampling import Sampling
from raspv_spv.simulator import PhospheneSimulator

K = CameraIntrinsics.from_hfov(320, 240, 60.0)


def head_q(yaw_deg=0.0, pitch_deg=0.0):
    """Head quaternion (x, y, z, w): yaw about z (left), then pitch about y (down)."""
    y, p = math.radians(yaw_deg) / 2, math.radians(pitch_deg) / 2
    qz = np.array([0.0, 0.0, math.sin(y), math.cos(y)])
    qy = np.array([0.0, math.sin(p), 0.0, math.cos(p)])
    x1, y1, z1, w1 = qz
    x2, y2, z2, w2 = qy
    return (w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2)


def camera_turn(yaw_deg=0.0, pitch_deg=0.0):
    """R_{C0←C1} for a head turned by yaw/pitch from straight ahead (capture at rest)."""
    return OPTICAL_IN_HEAD.T @ quaternion_to_matrix(*head_q(yaw_deg, pitch_deg)) @ OPTICAL_IN_HEAD


@pytest.fixture(scope="module")
def sim():
    return PhospheneSimulator(spv_config("optimist", width=400, mode="grey", temporal=False))


# -- the homography -----------------------------------------------------------------------------

def test_turned_sampling_is_the_homography_KC_R_KPinv(sim):
    base = sim.sampling(K)
    R = camera_turn(7.0, -4.0)
    turned = base.turned(R)
    P = np.column_stack([sim.map.centres, np.ones(sim.count)])
    h = (K.K @ R @ np.linalg.inv(sim.map.K) @ P.T).T
    assert np.allclose(turned.uv, h[:, :2] / h[:, 2:], atol=1e-9)
    assert np.array_equal(turned.inside, K.contains(*(h[:, :2] / h[:, 2:]).T))


def test_identity_turn_changes_nothing_and_a_left_turn_looks_left(sim):
    base = sim.sampling(K)
    same = base.turned(np.eye(3))
    assert np.allclose(same.uv, base.uv) and np.array_equal(same.rows, base.rows) and np.array_equal(same.cols, base.cols)
    left = base.turned(camera_turn(10.0))
    # the view turned 10° left shows, at each phosphene, what lay left of it in the captured image
    centre = np.argmin(np.linalg.norm(sim.map.centres - [200, 200], axis=1))
    assert left.uv[centre, 0] < base.uv[centre, 0] - K.fx * math.tan(math.radians(9.0))
    with pytest.raises(ValueError):
        left.turned(np.eye(3))                              # only the unturned sampling turns


def test_rays_behind_the_camera_are_outside_and_sample_the_fill(sim):
    base = sim.sampling(K)
    back = base.turned(camera_turn(180.0))
    assert not back.inside.any()
    image = np.full((K.height, K.width), 9, np.uint8)
    assert (back.sample(image, fill=0) == 0).all()
    # a 40° turn from a 60° camera leaves a 45° field partly outside: those phosphenes get the fill
    part = base.turned(camera_turn(40.0))
    values = part.sample(image, fill=0)
    assert 0 < (values == 9).sum() < sim.count and np.array_equal(values == 9, part.inside)


def test_depth_at_another_resolution_uses_the_turned_rays(sim):
    turned = sim.sampling(K).turned(camera_turn(5.0, 3.0))
    half = turned.for_shape(120, 160)
    expect = K.scaled(160, 120).project(turned.rays)
    assert np.allclose(half.uv[:, 0], expect[0], equal_nan=True)
    assert half.capture_from_display is turned.capture_from_display


def test_projected_lines_land_where_the_turned_view_sees_them(sim):
    """A world-fixed polyline drawn into a turned view = the same line, turned, in an unturned view."""
    R = camera_turn(6.0, 2.0)
    line = np.column_stack([np.linspace(-1.0, 1.0, 80), np.full(80, 0.8), np.full(80, 3.0)])   # C0, m
    base = sim.sampling(K)
    turned = phosphenes_on_lines(line, base.turned(R), 2.0)
    expected = phosphenes_on_lines(line @ R, base, 2.0)                  # Rᵀ·p: the line in C1
    assert turned.sum() > 10 and np.array_equal(turned, expected)
    assert not np.array_equal(turned, phosphenes_on_lines(line, base, 2.0))


# -- where the view points ------------------------------------------------------------------------

def test_head_only_the_turn_between_capture_and_display_head():
    v = ViewTracker()
    assert v.capture_from_display(1.0, 1.1) is None                     # no head orientation yet
    v.add_head(0.90, head_q(0.0))
    v.add_head(1.05, head_q(20.0))
    R = v.capture_from_display(1.0, 1.2)       # head at 1.0 interpolated: 2/3 of the way to 20°
    assert rotation_angle_deg(R) == pytest.approx(20.0 - 20.0 * (0.10 / 0.15), abs=1e-6)
    assert np.allclose(v.capture_from_display(1.05, 1.2), np.eye(3), atol=1e-9)
    assert np.allclose(v.capture_from_display(0.5, 5.0), camera_turn(20.0), atol=1e-9)   # head held


def base_pose(yaw_deg, x=1.0, y=2.0):
    T = np.eye(4)
    T[:3, :3] = quaternion_to_matrix(*head_q(yaw_deg))
    T[:3, 3] = (x, y, 0.0)
    return T


def camera_pose(base_yaw, head_yaw, head_pitch=0.0):
    T = base_pose(base_yaw)
    C = np.eye(4)
    C[:3, :3] = quaternion_to_matrix(*head_q(head_yaw, head_pitch)) @ OPTICAL_IN_HEAD
    C[:3, 3] = (0.08, 0.0, 1.6)
    return T @ C


def test_with_odometry_the_head_the_frame_was_rendered_with_comes_from_the_poses():
    """The simulator renders with the head it had, not the one the bridge stamped: camera pose
    and odometry at the frame's stamp say which."""
    v = ViewTracker()
    v.add_head(0.0, head_q(0.0))
    v.add_head(0.99, head_q(30.0))           # sent just before the frame, but not yet applied by the sim
    v.add_camera_pose(1.0, camera_pose(50.0, 0.0))
    v.add_odometry(1.0, base_pose(50.0), 0.0)
    R = v.capture_from_display(1.0, 1.01)
    assert np.allclose(R, camera_turn(30.0), atol=1e-9)                  # the full 30°, not 0
    # the same frame without odometry would trust the head stamps (and see no turn)
    w = ViewTracker()
    w.add_head(0.0, head_q(0.0))
    w.add_head(0.99, head_q(30.0))
    w.add_camera_pose(1.0, camera_pose(50.0, 0.0))
    assert rotation_angle_deg(w.capture_from_display(1.0, 1.01)) == pytest.approx(0.0, abs=1e-9)


def test_the_base_turn_is_predicted_from_the_odometry_yaw_rate():
    v = ViewTracker()
    v.add_head(0.0, head_q(0.0))
    v.add_camera_pose(1.0, camera_pose(10.0, 0.0))
    v.add_odometry(1.0, base_pose(10.0), math.radians(90.0))            # turning left at 90°/s
    R = v.capture_from_display(1.0, 1.1)
    assert np.allclose(R, camera_turn(9.0), atol=1e-9)                   # 0.1 s × 90°/s
    R = v.capture_from_display(1.0, 3.0)                                 # prediction capped at 0.25 s
    assert rotation_angle_deg(R) == pytest.approx(22.5, abs=1e-6)


def test_bad_poses_are_refused():
    v = ViewTracker()
    with pytest.raises(ValueError):
        v.add_head(0.0, (0.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError):
        v.add_odometry(0.0, base_pose(0.0), float("nan"))
    bad = np.eye(4)
    bad[0, 3] = np.nan
    with pytest.raises(ValueError):
        v.add_camera_pose(0.0, bad)


# -- which frame, and the display ---------------------------------------------------------------------

def frame_at(stamp, levels=None, inputs=None):
    return DisplayFrame(stamp, inputs or FrameInputs(stamp=stamp), levels if levels is not None else np.zeros(3, np.uint8), 1)


def test_frame_history_gives_the_frame_captured_latency_ago():
    h = FrameHistory(keep_s=0.5)
    assert h.pick(1.0) is None
    for k in range(10):
        h.add(frame_at(1.0 + 0.05 * k), latency_s=0.2)
    assert h.pick(10.0).stamp == pytest.approx(1.45)                     # no latency: the newest
    assert h.pick(1.50, 0.2).stamp == pytest.approx(1.30)
    assert h.pick(1.52, 0.2).stamp == pytest.approx(1.30)
    assert h.pick(1.10, 0.2) is None                                    # nothing that old kept yet
    assert len(h) <= 10
    h.add(frame_at(0.2))                                                 # time jumped back: a loop
    assert len(h) == 1 and h.pick(0.2).stamp == 0.2


def test_a_frame_recomputed_with_its_own_pose_replaces_the_shown_one():
    h = FrameHistory(keep_s=0.5)
    h.add(frame_at(1.0))
    h.add(frame_at(1.05, levels=np.full(3, 7, np.uint8)))       # shown with a predicted pose
    h.add(frame_at(1.05, levels=np.full(3, 9, np.uint8)))       # again once its pose came
    assert len(h) == 2 and h.newest().levels[0] == 9
    h.add(frame_at(1.02, levels=np.full(3, 5, np.uint8)))       # a scene result of an earlier frame, late
    assert len(h) == 2 and h.newest().stamp == 1.05             # the display does not go back


def test_frame_history_forgets_what_no_display_needs():
    h = FrameHistory(keep_s=0.5)
    for k in range(200):
        h.add(frame_at(0.05 * k), latency_s=0.3)
    assert len(h) <= (0.5 + 0.3) / 0.05 + 2


def textured(camera):
    """A colour image with a horizontal ramp: turning the view changes every grey level."""
    u = np.linspace(0, 255, camera.width, dtype=np.float32)
    return np.repeat(np.broadcast_to(u, (camera.height, camera.width))[..., None], 3, axis=2).astype(np.uint8)


def test_display_view_resamples_the_last_frame_for_the_newest_head(sim):
    view = DisplayView(reprojection=True)
    inputs = FrameInputs(color=textured(K), camera=K, stamp=1.0)
    captured = sim.levels(inputs)
    view.tracker.add_head(0.9, head_q(0.0))
    view.tracker.add_head(1.0, head_q(0.0))                             # the head when the frame was taken
    view.add_frame(DisplayFrame(1.0, inputs, captured, 1))
    levels, frame = view.levels_at(sim, 1, 1.02)
    assert frame.stamp == 1.0 and levels is captured                          # head still: as captured
    view.tracker.add_head(1.03, head_q(8.0))
    levels, _ = view.levels_at(sim, 1, 1.04)
    assert np.array_equal(levels, sim.levels(inputs, capture_from_display=camera_turn(8.0)))
    assert (levels != captured).mean() > 0.3
    assert view.levels_at(sim, 1, 1.06)[0] is levels                    # same turn: computed once
    assert view.turned_ticks == 1
    assert view.levels_at(sim, 2, 1.06) is None                         # another map: nothing yet
    view.configure(reprojection=False, latency_ms=0.0)
    assert view.levels_at(sim, 1, 1.08)[0] is captured


def test_device_latency_shows_the_scene_as_captured_that_long_ago(sim):
    view = DisplayView(reprojection=True, latency_ms=100.0)
    view.tracker.add_head(0.0, head_q(0.0))
    inputs = {}
    for k in range(8):
        t = round(1.0 + 0.05 * k, 6)
        inputs[t] = FrameInputs(color=textured(K), camera=K, stamp=t)
        view.add_frame(DisplayFrame(t, inputs[t], sim.levels(inputs[t]), 1))
        view.tracker.add_head(t + 0.01, head_q(2.0 * k))                # the head keeps turning
    assert view.levels_at(sim, 1, 1.05) is None                         # nothing captured by 0.95 s
    levels, frame = view.levels_at(sim, 1, 1.32)
    assert frame.stamp == 1.20                                          # the newest captured ≤ 1.32 − 0.1
    # turned from the head at 1.20 (7.6°: between 6° sent at 1.16 and 8° at 1.21) to the head at
    # 1.22 (8.4°), not to the newest (14°)
    R = view.tracker.capture_from_display(1.20, 1.22)
    assert rotation_angle_deg(R) == pytest.approx(0.8, abs=1e-3)          # slerp as nlerp below 1.8°
    assert np.array_equal(levels, sim.levels(inputs[1.20], capture_from_display=R))


def test_a_turn_the_mode_cannot_compute_shows_the_frame_as_captured():
    chess = PhospheneSimulator(spv_config("optimist", width=400, mode="chess_floor", temporal=False))
    view = DisplayView()
    inputs = FrameInputs(color=textured(K), camera=K, stamp=1.0)          # no scene: chess cannot run
    captured = np.zeros(chess.count, np.uint8)
    view.add_frame(DisplayFrame(1.0, inputs, captured, 1, chess))
    view.tracker.add_head(0.9, head_q(0.0))
    view.tracker.add_head(1.0, head_q(0.0))
    view.tracker.add_head(1.01, head_q(5.0))
    assert view.levels_at(chess, 1, 1.02)[0] is captured


def test_a_mode_changed_at_run_time_shows_on_the_last_frame_at_once(sim):
    """The display re-runs the new simulator on the frame it has (the next camera frame may be
    50 ms away), and shows nothing rather than the old mode's levels when it cannot."""
    view = DisplayView()
    inputs = FrameInputs(color=textured(K), camera=K, stamp=1.0)
    view.add_frame(DisplayFrame(1.0, inputs, sim.levels(inputs), 1, sim))
    edges = PhospheneSimulator(spv_config("optimist", width=400, mode="edges", temporal=False))
    levels, frame = view.levels_at(edges, 1, 1.02)
    assert frame.stamp == 1.0 and np.array_equal(levels, edges.levels(inputs))
    assert view.levels_at(edges, 1, 1.04)[0] is levels                  # computed once
    chess = PhospheneSimulator(spv_config("optimist", width=400, mode="chess_floor", temporal=False))
    assert view.levels_at(chess, 1, 1.06) is None                       # no scene in this frame yet


def test_sampling_built_without_a_turn_has_no_rotation():
    m = PhospheneMap.build(spv_config("argus_ii", width=200).map_spec())
    s = Sampling.build(m, K)
    assert s.capture_from_display is None
    pts = np.ones((3, 3))
    assert s.to_display(pts) is pts
