"""Eye gaze on the display (raspv_spv.gaze): field offset, gaze-contingent sampling through
K_C·R·K_P⁻¹ (with the head's reprojection), saccade detection and what a saccade shows."""
import math

import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.gaze import (MAX_SACCADE_S, NO_GAZE, GazeError, GazeTracker, angle_between_deg,
                            direction_from_angles, field_offset_px, gaze_angles_deg, gaze_display,
                            gaze_rotation_optical, shift_image, unit_direction)
from raspv_spv.reprojection import OPTICAL_IN_HEAD, DisplayFrame, DisplayView
from raspv_spv.simulator import PhospheneSimulator

K = CameraIntrinsics.from_hfov(320, 240, 60.0)


@pytest.fixture(scope="module")
def sim():
    return PhospheneSimulator(spv_config("optimist", width=400, mode="grey", temporal=False))


def test_directions_angles_and_offsets():
    d = direction_from_angles(10.0, -5.0)          # 10° left, 5° up
    assert np.isclose(np.linalg.norm(d), 1.0)
    assert np.allclose(gaze_angles_deg(d), (10.0, -5.0))
    f = 500.0
    dx, dy = field_offset_px(d, f)
    # left → the field moves left on the display (x right); up → it moves up (y down)
    assert dx == pytest.approx(-f * math.tan(math.radians(10.0)))
    assert dy == pytest.approx(f * math.tan(math.radians(-5.0)) / math.cos(math.radians(10.0))) and dy < 0
    # the field's centre lands where K_P projects the gaze direction
    g_opt = OPTICAL_IN_HEAD.T @ d
    assert (dx, dy) == pytest.approx((f * g_opt[0] / g_opt[2], f * g_opt[1] / g_opt[2]))
    with pytest.raises(GazeError):
        unit_direction((0.0, 0.0, 0.0))
    with pytest.raises(GazeError):
        unit_direction((-1.0, 0.2, 0.0))          # behind the head


def test_gaze_rotation_takes_the_optical_axis_to_the_gaze():
    d = direction_from_angles(-12.0, 8.0)
    G = gaze_rotation_optical(d)
    assert np.allclose(G @ G.T, np.eye(3)) and np.isclose(np.linalg.det(G), 1.0)
    assert np.allclose(G @ [0.0, 0.0, 1.0], OPTICAL_IN_HEAD.T @ d)


def test_shift_image_translates_with_black_fill():
    img = np.arange(1, 5 * 7 + 1, dtype=np.uint8).reshape(5, 7)
    out = shift_image(img, 2, -1)
    assert out[0, 2] == img[1, 0] and out[3, 6] == img[4, 4]
    assert not out[:, :2].any() and not out[4, :].any()
    assert shift_image(img, 0, 0) is img and not shift_image(img, 9, 0).any()
    rgb = np.stack([img] * 3, axis=2)
    assert np.array_equal(shift_image(rgb, -3, 2)[..., 1], shift_image(img, -3, 2))


def test_drawn_field_follows_the_gaze_within_one_phosphene_spacing(sim):
    """All phosphenes lit: the image's centroid moves by the gaze's field offset (tolerance: one
    phosphene spacing, the target; cropping at the image's edge is what moves it at all)."""
    levels = np.full(sim.count, sim.num_levels - 1, np.uint8)
    base = sim.render(sim.brightness(levels))
    for yaw, pitch in [(5.0, 0.0), (-8.0, 4.0), (3.0, -6.0)]:
        d = direction_from_angles(yaw, pitch)
        g = gaze_display("locked", "blank", _fixating(d), sim.map.focal_px)
        shown = shift_image(base, *g.offset_px)
        expected = np.array(field_offset_px(d, sim.map.focal_px))
        # compare the lit phosphenes' positions: a phosphene's peak moves by the offset exactly
        ys, xs = np.nonzero(base == base.max())
        ys2, xs2 = np.nonzero(shown == base.max())
        inner = (xs + g.offset_px[0] >= 0) & (xs + g.offset_px[0] < base.shape[1]) & \
                (ys + g.offset_px[1] >= 0) & (ys + g.offset_px[1] < base.shape[0])
        assert set(zip(xs[inner] + g.offset_px[0], ys[inner] + g.offset_px[1])) == set(zip(xs2, ys2))
        assert np.all(np.abs(np.array(g.offset_px) - expected) <= 0.5)
        assert np.all(np.abs(np.array(g.offset_px) - expected) < sim.map.spacing_x)


def _fixating(d):
    tracker = GazeTracker()
    tracker.add(0.0, d, True, now=0.0)
    return tracker.state(0.0)


def _gradient_frame():
    u, v = np.meshgrid(np.arange(K.width), np.arange(K.height))
    color = np.stack([(u * 255 // (K.width - 1)).astype(np.uint8), (v * 255 // (K.height - 1)).astype(np.uint8),
                      np.zeros_like(u, np.uint8)], axis=2)
    return FrameInputs(color=color, camera=K, stamp=1.0)


def test_contingent_sampling_turns_by_the_gaze_through_KC_G_KPinv(sim):
    d = direction_from_angles(9.0, -4.0)
    G = gaze_display("contingent", "blank", _fixating(d), sim.map.focal_px).sampling_rotation
    assert np.allclose(G, gaze_rotation_optical(d))
    turned = sim.sampling(K).turned(G)
    P = np.column_stack([sim.map.centres, np.ones(sim.count)])
    h = (K.K @ G @ np.linalg.inv(sim.map.K) @ P.T).T
    assert np.allclose(turned.uv, h[:, :2] / h[:, 2:], atol=1e-9)
    # the field's centre samples the camera where the eye looks
    centre_ray = np.linalg.inv(sim.map.K) @ [sim.map.K[0, 2], sim.map.K[1, 2], 1.0]
    g_opt = OPTICAL_IN_HEAD.T @ d
    assert np.allclose(G @ centre_ray, g_opt)
    # locked: no rotation, the sampling stays straight ahead
    assert gaze_display("locked", "blank", _fixating(d), sim.map.focal_px).sampling_rotation is None


def test_contingent_levels_compose_with_the_head_reprojection(sim):
    """DisplayView.levels_at: sampling rotation R_{C0←C1}·G — the head's turn, then the eye's."""
    view = DisplayView(reprojection=True, camera_source="sim")
    inputs = _gradient_frame()
    frame = DisplayFrame(1.0, inputs, sim.levels(inputs), 1, sim)
    view.add_frame(frame)
    view.tracker.add_head(1.0, (0.0, 0.0, 0.0, 1.0))
    yaw = math.radians(6.0)
    view.tracker.add_head(1.5, (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))     # the head turned 6° left
    G = gaze_rotation_optical(direction_from_angles(-4.0, 3.0))
    levels, shown = view.levels_at(sim, 1, 1.5, G)
    R_head = view.tracker.capture_from_display(1.0, 1.5)
    expected = sim.levels(inputs, capture_from_display=R_head @ G)
    assert shown is frame and np.array_equal(levels, expected)
    # without the gaze the levels are the head's alone; with the gaze alone (no head) G alone
    assert np.array_equal(view.levels_at(sim, 1, 1.5)[0], sim.levels(inputs, capture_from_display=R_head))
    fixed = DisplayView(reprojection=False)
    fixed.add_frame(frame)
    assert np.array_equal(fixed.levels_at(sim, 1, 1.5, G)[0], sim.levels(inputs, capture_from_display=G))
    # the content moved: a gaze 4° right samples the redder right of the gradient at the centre
    assert not np.array_equal(fixed.levels_at(sim, 1, 1.5, G)[0], frame.levels)


def test_saccades_by_velocity_threshold_and_what_they_show():
    tr = GazeTracker(saccade_threshold_deg_s=30.0)
    dt, t = 1 / 120, 0.0
    start = direction_from_angles(0.0, 0.0)
    for _ in range(12):                          # fixation with 0.05° jitter: 6 deg/s < 30
        t += dt
        tr.add(t, direction_from_angles(0.05 * np.sin(t * 50), 0.0), True, now=t)
    assert not tr.state(t).saccade
    seen = []
    for k in range(1, 7):                        # a 12° saccade over 50 ms (240 deg/s)
        t += dt
        tr.add(t, direction_from_angles(2.0 * k, 0.0), True, now=t)
        seen.append(tr.state(t))
    assert all(s.saccade for s in seen) and tr.saccades == 1
    held = gaze_display("locked", "hold", seen[-1], 500.0)
    assert held.offset_px == pytest.approx(gaze_display("locked", "follow", _fixating(start), 500.0).offset_px, abs=1)
    assert gaze_display("locked", "blank", seen[-1], 500.0).blank
    assert not gaze_display("locked", "follow", seen[-1], 500.0).blank
    t += dt
    tr.add(t, direction_from_angles(12.0, 0.0), True, now=t)           # landed
    s = tr.state(t)
    assert not s.saccade and angle_between_deg(s.direction, direction_from_angles(12.0, 0.0)) < 1e-9
    # a saccade whose samples stop is over after MAX_SACCADE_S
    tr.add(t + dt, direction_from_angles(20.0, 0.0), True, now=t + dt)
    assert tr.state(t + dt).saccade and not tr.state(t + dt + MAX_SACCADE_S + 0.01).saccade
    # invalid samples (a blink) keep the last valid direction
    tr.add(t + 2 * dt, None, False, now=t + 2 * dt)
    s = tr.state(t + 2 * dt)
    assert not s.valid and angle_between_deg(s.direction, direction_from_angles(20.0, 0.0)) < 1e-9


def test_no_valid_gaze_and_ignored_keep_the_field_centred():
    assert gaze_display("contingent", "blank", GazeTracker().state(0.0), 500.0) is NO_GAZE
    assert gaze_display("ignored", "blank", _fixating(direction_from_angles(10, 0)), 500.0) is NO_GAZE
    with pytest.raises(ValueError):
        gaze_display("sideways", "blank", None, 500.0)


def test_tracker_asks_for_a_frame_only_when_the_gaze_visibly_moved():
    tr = GazeTracker()
    assert tr.add(0.0, direction_from_angles(0, 0), True, now=0.0)
    assert not tr.add(0.01, direction_from_angles(0.02, 0), True, now=0.01)
    assert tr.add(0.02, direction_from_angles(1.0, 0), True, now=0.02)    # 100°/s: a saccade, and moved
