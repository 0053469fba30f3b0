"""Stale inputs of the spv node (core, no ROS): bounds, detection, what is shown, the no-data ring."""
import numpy as np
import pytest

from raspv_common.intrinsics import CameraIntrinsics
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.no_data import NoDataPattern, ring_mask
from raspv_spv.simulator import PhospheneSimulator
from raspv_spv.staleness import (ALIVE, FALLBACK_MODE, GONE, LATE_S, NO_DATA, PAUSED, RECOVER_S, UNKNOWN,
                                 UNKNOWN_BOUND_S,
                                 StalenessMonitor, expected_with, late_bound, plan_display, required_inputs,
                                 stale_bound, watched_inputs)

TICK_S = 0.02          # one display tick at 50 Hz
TARGET_S = 0.3         # detected and shown within this long after the last message (issue 16)


@pytest.mark.parametrize("rate_hz", [10.0, 15.0, 20.0, 30.0, 60.0])
def test_inputs_at_10_hz_or_faster_are_detected_and_shown_within_300_ms(rate_hz):
    assert stale_bound(1.0 / rate_hz) + TICK_S <= TARGET_S
    assert stale_bound(1.0 / rate_hz) >= 2.0 / rate_hz        # one lost message is not a stall


def test_the_bound_never_falls_inside_a_slow_inputs_own_period():
    assert stale_bound(None) == UNKNOWN_BOUND_S
    for period in (0.25, 0.5, 1.0, 2.0):
        assert stale_bound(period) > period


def feed(monitor, name, start, period, count):
    for i in range(count):
        monitor.arrived(name, start + i * period)
    return start + (count - 1) * period


def test_monitor_learns_each_inputs_period_and_flags_it_after_its_bound():
    m = StalenessMonitor()
    m.watch({"scene", "depth", "camera_pose", "camera"})
    assert m.watched == {"scene", "depth"}                   # pose, head, odometry are not watched
    assert m.check(0.0) == frozenset()                       # never arrived: not stale
    last_depth = feed(m, "depth", 0.0, 1 / 30, 30)
    last_scene = feed(m, "scene", 0.0, 0.1, 10)
    assert m.check(last_scene + 0.05) == frozenset()
    # depth at 30 Hz: stale 0.1 s (the floor) after its last message; scene at 10 Hz: after 0.26 s
    # (not before 0.5 s while fewer than 3 intervals are known)
    assert m.check(last_depth + 0.11) == {"depth"}
    assert m.check(last_scene + 0.25) == {"depth"}
    assert m.check(last_scene + 0.27) == {"depth", "scene"}
    assert m.episodes == 2
    # back: one message clears it at once; the long gap does not change the learned period
    m.arrived("scene", last_scene + 3.0)
    assert m.check(last_scene + 3.01) == {"depth"}
    assert "expected every 0.10 s" in m.describe("scene", last_scene + 3.5)


def test_a_sources_first_irregular_frames_are_not_a_stall():
    m = StalenessMonitor()
    m.watch({"depth"})
    for t in (0.0, 0.05, 0.45):                     # two intervals: the period is not trusted yet
        m.arrived("depth", t)
    assert m.check(0.45 + 0.4) == frozenset()
    assert m.check(0.45 + UNKNOWN_BOUND_S + 0.01) == {"depth"}


def test_scene_inputs_that_never_came_are_stale_once_the_camera_flows():
    m = StalenessMonitor()
    needs = frozenset({"scene", "scene_labels", "camera"})
    m.watch(watched_inputs(needs, []), expected_with(needs))
    assert m.check(10.0) == frozenset()                       # nothing at all yet: dark, as before
    last = feed(m, "depth", 10.0, 0.1, 4)                     # the camera flows (period known: bound 0.26 s)
    assert m.check(last + 0.05) == {"scene", "scene_labels"}  # 0.35 s of camera, no scene
    m.arrived("scene", last + 0.06)
    m.arrived("scene_labels", last + 0.06)
    assert m.check(last + 0.07) == frozenset()
    assert expected_with(frozenset({"color", "camera"})) == {}


def test_an_alive_producer_is_late_not_stale_until_its_late_bound():
    """Dead or slow: the same gap is a fault from a dead (or foreign) producer and lateness from a
    live one (issue 21)."""
    m = StalenessMonitor()
    m.watch({"scene", "depth"})
    last = feed(m, "scene", 0.0, 0.1, 10)
    feed(m, "depth", 0.0, 0.1, 10)
    gap = last + 0.5                                              # twice the dead-producer bound
    assert m.check(gap, {"scene": ALIVE, "depth": ALIVE}) == frozenset()
    assert m.check(gap, {"scene": GONE, "depth": ALIVE}) == {"scene"}
    assert m.check(gap) == {"scene", "depth"}                     # nothing known of the producers: gaps alone
    assert m.episodes == 2 and m.late_episodes == 0
    assert late_bound(0.1) == LATE_S and late_bound(0.5) == 1.5   # a slow input: 3 of its periods
    m2 = StalenessMonitor()
    m2.watch({"scene"})
    last = feed(m2, "scene", 0.0, 0.1, 10)
    assert m2.check(last + LATE_S - 0.01, {"scene": ALIVE}) == frozenset()
    assert m2.check(last + LATE_S + 0.01, {"scene": ALIVE}) == {"scene"}   # alive but hung: stale at last
    assert (m2.episodes, m2.late_episodes) == (1, 1)


def test_after_a_late_episode_an_input_counts_again_only_when_it_flows_again():
    m = StalenessMonitor()
    m.watch({"scene"})
    last = feed(m, "scene", 0.0, 0.1, 10)
    assert m.check(last + 1.2, {"scene": ALIVE}) == {"scene"}
    m.arrived("scene", last + 1.25)                               # one late message: still stale (hysteresis)
    assert m.check(last + 1.26, {"scene": ALIVE}) == {"scene"}
    m.arrived("scene", last + 1.25 + RECOVER_S + 0.1)             # the next one too slow as well
    assert m.check(last + 1.25 + RECOVER_S + 0.11, {"scene": ALIVE}) == {"scene"}
    t = last + 1.25 + RECOVER_S + 0.1
    m.arrived("scene", t + 0.1)                                   # two close together: back
    assert m.check(t + 0.11, {"scene": ALIVE}) == frozenset()
    assert m.episodes == 1


def test_a_paused_source_is_never_stale_and_a_camera_never_seen_shows_the_ring():
    m = StalenessMonitor()
    needs = frozenset({"depth", "camera"})
    m.watch(watched_inputs(needs, []), expected_with(needs), required_inputs(needs))
    assert m.check(0.0) == {"depth"}                              # the camera never delivered: the ring
    assert m.episodes == 0                                        # ... but waiting is not an episode
    last = feed(m, "depth", 1.0, 0.05, 10)
    assert m.check(last + 0.01) == frozenset()
    assert m.check(last + 60.0, {"depth": PAUSED}) == frozenset()  # a replay paused by the user
    assert m.check(last + 60.0, {"depth": GONE}) == {"depth"}
    assert required_inputs(frozenset({"scene_labels", "camera"})) == {"depth"}
    assert required_inputs(frozenset({"color", "camera"})) == {"color"}


def test_a_source_resuming_from_a_pause_gets_its_late_bound_from_the_moment_it_resumes():
    """A recording reopened to loop (or a replay the user resumes) announces paused, then
    delivering: its first frame after that is not overdue (no ring between the two)."""
    m = StalenessMonitor()
    m.watch({"depth"})
    last = feed(m, "depth", 0.0, 1 / 30, 30)
    assert m.check(last + 0.5, {"depth": PAUSED}) == frozenset()
    resumed = last + 2.0
    assert m.check(resumed, {"depth": ALIVE}) == frozenset()        # 2 s after its last frame
    assert m.check(resumed + LATE_S - 0.01, {"depth": ALIVE}) == frozenset()
    assert m.check(resumed + LATE_S + 0.01, {"depth": ALIVE}) == {"depth"}   # and no first frame since
    assert m.episodes == 1


def test_scene_outputs_never_seen_wait_longer_for_a_live_scene_node():
    m = StalenessMonitor()
    needs = frozenset({"scene", "scene_labels", "camera"})
    m.watch(watched_inputs(needs, []), expected_with(needs), required_inputs(needs))
    last = feed(m, "depth", 10.0, 0.1, 4)
    alive = {"scene": ALIVE, "scene_labels": ALIVE, "depth": ALIVE}
    assert m.check(last + 0.05, alive) == frozenset()             # the scene node starting: wait for it
    assert m.check(10.0 + LATE_S + 0.01, alive) == {"scene", "scene_labels"}
    assert m.episodes == 0


def test_check_returns_the_same_set_while_nothing_changes():
    m = StalenessMonitor()
    m.watch({"depth"})
    feed(m, "depth", 0.0, 0.05, 5)
    a, b = m.check(0.21), m.check(0.22)
    assert a is b


def test_watch_keeps_the_clocks_of_inputs_still_watched():
    m = StalenessMonitor()
    m.watch({"depth", "scene"})
    last = feed(m, "depth", 0.0, 0.05, 5)
    m.watch({"depth", "nav_path"})
    assert m.watched == {"depth", "nav_path"}
    assert m.check(last + 1.0) == {"depth"}


SCENE_NEEDS = frozenset({"scene_labels", "camera"})
OVERLAYS = [("path", frozenset({"camera", "camera_pose", "depth", "nav_path"})),
            ("stairs", frozenset({"camera", "stairs"}))]


def test_plan_falls_back_to_depth_when_the_scene_is_stale_and_drops_overlays_whose_input_is():
    assert plan_display("wall_obstacles", SCENE_NEEDS, OVERLAYS, frozenset()).normal
    p = plan_display("wall_obstacles", SCENE_NEEDS, OVERLAYS, frozenset({"scene_labels"}))
    assert (p.mode, p.overlays, p.normal, p.no_data) == (FALLBACK_MODE, ("path", "stairs"), False, False)
    p = plan_display("wall_obstacles", SCENE_NEEDS, OVERLAYS, frozenset({"stairs"}))
    assert (p.mode, p.overlays, p.normal) == ("wall_obstacles", ("path",), False)
    p = plan_display("grey", frozenset({"color", "camera"}), OVERLAYS, frozenset({"nav_path", "stairs"}))
    assert (p.mode, p.overlays) == ("grey", ())


def test_plan_shows_the_no_data_pattern_when_the_camera_is_stale():
    assert plan_display("grey", frozenset({"color", "camera"}), OVERLAYS, frozenset({"color"})).mode == NO_DATA
    # colour mode: a stale depth only drops the overlays that read depth
    p = plan_display("grey", frozenset({"color", "camera"}), OVERLAYS, frozenset({"depth"}))
    assert (p.mode, p.overlays) == ("grey", ("stairs",))
    # scene mode: its fallback needs depth
    assert plan_display("wall_obstacles", SCENE_NEEDS, [], frozenset({"scene_labels", "depth"})).no_data
    assert plan_display("depth", frozenset({"depth", "camera"}), [], frozenset({"depth"})).no_data


def test_watched_inputs_include_the_fallbacks_camera_for_scene_modes():
    assert watched_inputs(SCENE_NEEDS, [o for _, o in OVERLAYS]) == {"scene_labels", "depth", "nav_path", "stairs"}
    assert watched_inputs(frozenset({"color", "camera"}), []) == {"color"}


def test_the_no_data_ring_is_a_sparse_dotted_border_that_blinks():
    sim = PhospheneSimulator(spv_config("default", width=200, num_phosphenes=400, temporal=False))
    pattern = NoDataPattern.for_simulator(sim)
    on = pattern.levels(0.1)
    off = pattern.levels(0.35)
    assert not off.any() and pattern.levels(0.6) is on
    lit = np.flatnonzero(on)
    assert set(on[lit]) == {sim.num_levels - 1}
    assert 0.05 * sim.count < lit.size < 0.25 * sim.count     # sparse
    xy = sim.map.display_centres
    inner = np.abs(xy - xy.mean(axis=0)).max(axis=1)
    assert inner[lit].min() > 0.6 * inner.max()               # only near the border
    # around the border: every side of the field has dots
    centre = xy.mean(axis=0)
    angles = np.degrees(np.arctan2(*(xy[lit] - centre).T[::-1]))
    assert np.histogram(angles, bins=8, range=(-180, 180))[0].min() > 0


def test_the_ring_follows_a_circular_field_and_skips_dropped_phosphenes():
    centres = np.array([[np.cos(a) * r, np.sin(a) * r] for r in np.linspace(1, 10, 10)
                        for a in np.linspace(0, 2 * np.pi, int(6 * r), endpoint=False)])
    dropped = np.zeros(len(centres), bool)
    dropped[-3:] = True
    mask = ring_mask(centres, dropped, circular=True)
    radius = np.hypot(*centres.T)
    assert radius[mask].min() >= 8.5 and not mask[dropped].any()


def test_a_fallback_variant_shares_the_simulators_state_and_runs_the_fallback_mode():
    sim = PhospheneSimulator(spv_config("default", width=160, num_phosphenes=200, mode="wall_obstacles",
                                        overlays=("stairs",), temporal=True))
    fallback = sim.variant(FALLBACK_MODE, ())
    assert fallback.config.mode == "depth" and fallback.overlays == [] and fallback.temporal is sim.temporal
    assert fallback.renderer is sim.renderer and sim.config.mode == "wall_obstacles"
    cam = CameraIntrinsics(160, 120, 100.0, 100.0, 80.0, 60.0)
    depth = np.full((120, 160), 2.0, np.float32)
    levels = fallback.levels(FrameInputs(depth=depth, camera=cam))
    assert levels.shape == (sim.count,) and levels.any()


def test_an_episode_whose_producer_is_seen_alive_later_counts_as_late_once():
    """Issue 36: the spv node logged a scene episode as "its node alive but late" and its summary
    said "0 of them late from a live node": the episode began while the producer's state was not
    known yet (gaps alone) and the producer was seen alive while the input was still stale."""
    m = StalenessMonitor()
    m.watch({"scene"})
    last = feed(m, "scene", 0.0, 0.1, 10)
    assert m.check(last + 0.3, {"scene": UNKNOWN}) == {"scene"}
    assert (m.episodes, m.late_episodes) == (1, 0)
    assert m.check(last + LATE_S + 0.1, {"scene": ALIVE}) == {"scene"}
    assert "its node alive but late" in m.describe("scene", last + LATE_S + 0.1, ALIVE)
    assert m.check(last + LATE_S + 0.2, {"scene": ALIVE}) == {"scene"}
    assert (m.episodes, m.late_episodes) == (1, 1)
