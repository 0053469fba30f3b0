"""Guidance: the assistant's cues in the world frame, the overlay's edge marker, the audio cue positions."""
import math

import numpy as np
import pytest

from raspv_camera.synthetic_scene import SyntheticRoom, camera_rotation
from raspv_common.intrinsics import CameraIntrinsics
from raspv_hmd.audio_cues import CueSettings, cues_message, listener_from_world
from raspv_nav.assistant import NavigationAssistant
from raspv_nav.guidance import Guidance, nearest_obstacle_ahead
from raspv_nav.motion import MapAlignment, planar_transform
from raspv_common.occupancy import OCCUPIED, OccupancyGrid
from raspv_perception.stair_model import Staircase, StairDirection
from raspv_spv.config import spv_config
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.guidance_overlay import GuidanceOverlay
from raspv_spv.phosphene_map import PhospheneMap
from raspv_spv.sampling import Sampling

CAM = CameraIntrinsics.from_hfov(320, 240, 60.0)


def corridor() -> OccupancyGrid:
    """12 m × 4 m room, walls around, 5 cm cells, origin at (0, 0)."""
    cells = np.zeros((80, 240), np.int8)
    cells[:2], cells[-2:], cells[:, :2], cells[:, -2:] = OCCUPIED, OCCUPIED, OCCUPIED, OCCUPIED
    return OccupancyGrid(cells, 0.05, (0.0, 0.0))


def guidance(waypoint, stamp=0.0) -> Guidance:
    return Guidance(stamp, True, False, "", np.array([1.6, 0.0]), math.pi / 2,
                    None if waypoint is None else np.asarray(waypoint, float), 5.0, 0.5, 0.0, True, None, math.inf)


def overlay_inputs(g, path=None, depth=True):
    room = SyntheticRoom(CAM, boxes=[])
    pose = room.pose_at(0.0)                          # at (1.6, 0, 1.6) looking along +y, 15° down
    _, rendered = room.render(pose)
    extras = {"nav_guidance": g}
    if path is not None:
        extras["nav_path"] = np.asarray(path, float)
    inputs = FrameInputs(depth=rendered if depth else None, camera=CAM, camera_pose=pose, extras=extras)
    pmap = PhospheneMap.build(spv_config("optimist", width=400).map_spec())
    return inputs, Sampling.build(pmap, CAM)


def test_marker_points_to_a_waypoint_outside_the_field():
    overlay = GuidanceOverlay()
    inputs, sampling = overlay_inputs(guidance([5.0, 1.0]))      # far to the right of the view
    lit = overlay.highlight(inputs, sampling)
    assert 3 < lit.sum() < 0.1 * sampling.count
    cx, cy = sampling.K_P[0, 2], sampling.K_P[1, 2]
    x, y = sampling.centres[lit].T
    assert (x > cx).all()                                       # on the right
    assert np.hypot(x - cx, y - cy).min() > 0.6 * np.hypot(*(sampling.centres - [cx, cy]).T).max()  # at the edge
    behind_left = overlay.highlight(*overlay_inputs(guidance([0.0, -2.0])))   # behind, to the left
    assert behind_left.any() and (sampling.centres[behind_left, 0] < cx).all()


def test_no_marker_while_the_path_or_the_waypoint_is_in_view_or_without_guidance():
    overlay = GuidanceOverlay()
    ahead = guidance([1.6, 2.5])
    assert not overlay.highlight(*overlay_inputs(ahead)).any()                 # the waypoint is in the field
    visible_path = [[1.6, 0.0], [1.6, 2.6], [3.5, 2.6]]                      # ahead, then right
    assert not overlay.highlight(*overlay_inputs(guidance([5.0, 1.0]), visible_path)).any()
    hidden_path = [[1.6, 0.0], [1.6, -2.0], [-3.0, -2.0]]                    # the path goes back
    assert overlay.highlight(*overlay_inputs(guidance([0.0, -2.0]), hidden_path)).any()
    assert not overlay.highlight(*overlay_inputs(None)).any()                  # before the first guidance


def test_assistant_guidance_frames_with_a_map_to_odometry_transform():
    """The same walk planned with the map placed in an odometry frame (rotated 90°, shifted)
    gives the same path, expressed in the odometry frame."""
    grid = corridor()
    plain = NavigationAssistant(grid, (11.0, 2.0))
    plain.set_subject(1.0, 1.0, 2.0, 0.0)
    p_map = plain.replan().path
    m_w = (3.0, 1.0, math.radians(90.0))                       # odometry origin at (3, 1) of the map, x along map y
    aligned = NavigationAssistant(grid, (11.0, 2.0), alignment=MapAlignment(m_w))
    W_M = np.linalg.inv(planar_transform(*m_w))
    start_w = W_M[:2, :2] @ [1.0, 2.0] + W_M[:2, 3]
    aligned.set_subject(1.0, start_w[0], start_w[1], -math.pi / 2)
    p_w = aligned.replan().path
    np.testing.assert_allclose(p_w, p_map @ W_M[:2, :2].T + W_M[:2, 3], atol=1e-9)
    g = aligned.guidance(aligned.velocity_hint((0.0, 0.0)))
    np.testing.assert_allclose(W_M[:2, :2].T @ (g.next_waypoint - W_M[:2, 3]), [1.0 + 0.8, 2.0], atol=0.05)
    assert g.heading == pytest.approx(-math.pi / 2) and g.has_path and g.feasible


def test_nearest_obstacle_ahead_ignores_walls_beside_the_corridor():
    grid = corridor()
    obstacles = grid.cells == OCCUPIED
    pos = np.array([6.0, 2.0])
    assert nearest_obstacle_ahead(obstacles, grid, pos, 0.0, 1.5, 60.0)[0] is None   # walls 1.9 m aside
    obstacles[38:42, 140:144] = True                             # something 1 m ahead
    point, dist = nearest_obstacle_ahead(obstacles, grid, pos, 0.0, 1.5, 60.0)
    assert dist == pytest.approx(1.025, abs=0.03) and point[0] > 6.9


def test_audio_cues_are_relative_to_the_listener():
    g = guidance([3.0, 4.0])
    g.nearest_obstacle, g.nearest_obstacle_distance = np.array([1.0, 3.0]), 1.0
    base = planar_transform(1.0, 2.0, math.pi / 2)               # standing at (1, 2) facing +y
    msg = cues_message(g, base, "base")
    assert msg["frame"] == "base"
    np.testing.assert_allclose(msg["waypoint"]["position"], [2.0, -2.0, 0.0], atol=1e-3)   # ahead, right
    np.testing.assert_allclose(msg["obstacle"]["position"], [1.0, 0.0, 0.0], atol=1e-3)    # straight ahead
    camera = np.eye(4)
    camera[:3, :3] = camera_rotation(math.pi / 2, 0.0)
    camera[:3, 3] = (1.0, 2.0, 1.6)
    head = cues_message(g, camera, "head")                        # listener = the camera, at eye height
    np.testing.assert_allclose(head["waypoint"]["position"], [2.0, -2.0, -1.6], atol=1e-3)
    np.testing.assert_allclose(listener_from_world(camera, "head") @ [1.0, 3.0, 1.6, 1.0], [1.0, 0.0, 0.0, 1.0],
                               atol=1e-12)
    stair_pose = np.eye(4)
    stair_pose[:3, 3] = (0.5, 1.2, 2.0)                          # camera frame: right, down, ahead
    stairs = Staircase(StairDirection.DESCENDING, stair_pose, 0.17, 0.28, 1.0, 2.0, [])
    s = cues_message(None, camera, "head", stairs)
    assert s["stairs"]["direction"] == "down" and s["waypoint"] is None
    np.testing.assert_allclose(s["stairs"]["position"], [2.0, -0.5, -1.2], atol=1e-3)
    far = Staircase(StairDirection.ASCENDING, stair_pose, 0.17, 0.28, 1.0, 9.0, [])
    assert cues_message(None, camera, "head", far)["stairs"] is None                     # beyond 4 m
    only_stairs = cues_message(g, base, "base", settings=CueSettings(enabled=("stairs",)))
    assert only_stairs["waypoint"] is None and only_stairs["obstacle"] is None
    assert cues_message(g, None, "base") is None


def test_non_finite_positions_never_reach_the_client_as_nan():
    g = guidance([float("nan"), 1.0])
    g.nearest_obstacle, g.nearest_obstacle_distance = np.array([1.0, 3.0]), float("nan")
    msg = cues_message(g, planar_transform(1.0, 2.0, 0.0), "base")
    assert msg["waypoint"] is None and msg["obstacle"] is None
    import json
    json.loads(json.dumps(msg, allow_nan=False))               # strict JSON
    bad = planar_transform(1.0, 2.0, 0.0)
    bad[0, 3] = float("inf")
    assert cues_message(g, bad, "base") is None
