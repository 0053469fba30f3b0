"""The planner node in a graph with the synthetic RGB-D source."""
from typing import NamedTuple

import numpy as np
import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Path
from raspv_msgs.msg import NavGuidance

from raspv_bringup.testing import RunningGraph
from raspv_camera.synthetic_scene import SyntheticRoom
from raspv_common import topics
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.qos import LATCHED_QOS
from raspv_common.occupancy import OCCUPIED, OccupancyGrid, save_map

pytestmark = pytest.mark.integration


class RoomGraph(NamedTuple):
    room: SyntheticRoom
    goal: list[float]
    graph: RunningGraph


def room_map(room: SyntheticRoom, res: float = 0.05) -> OccupancyGrid:
    """Floor plan of the synthetic room: walls around, boxes occupied."""
    w, h = room.size
    cells = np.zeros((int(round(h / res)), int(round(w / res))), np.int8)
    cells[:2], cells[-2:], cells[:, :2], cells[:, -2:] = OCCUPIED, OCCUPIED, OCCUPIED, OCCUPIED
    grid = OccupancyGrid(cells, res, (-w / 2, -h / 2))
    for box in room.boxes:
        lo = grid.world_to_cell([box.lo[:2]])[0]
        hi = grid.world_to_cell([box.hi[:2]])[0]
        cells[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1] = OCCUPIED
    return grid


class TestTheRoomGraph:
    """One graph (the synthetic room's camera, standing, and the planner on the room's map, the goal
    behind the low cabinet at x ∈ [2.3, 3.1], y ∈ [-0.6, 0.6]) for two tests in this order: the path,
    hint and costmaps, then the goal moved off the map (started once, stopped after the class)."""

    @pytest.fixture(scope="class")
    def room_graph(self, tmp_path_factory, ros_domain):
        tmp_path = tmp_path_factory.mktemp("room_graph")
        room = SyntheticRoom(CameraIntrinsics.from_hfov(64, 48, 60.0))
        save_map(room_map(room), tmp_path / "room.yaml")
        goal = [3.2, 1.5]
        g = RunningGraph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "planner"}]},
                          "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120, "walk_speed": 0.0}},
                          "planner": {"ros__parameters": {"map": str(tmp_path / "room.yaml"), "goal": goal}}}, tmp_path)
        yield RoomGraph(room, goal, g)
        code = g.stop()
        assert code == 0, f"the room graph ended with exit code {code}:\n{g.output[-3000:]}"

    def test_planner_publishes_a_path_to_the_goal_around_obstacles(self, room_graph, probe):
        room, goal = room_graph.room, room_graph.goal
        costmap = probe.wait_for_message("/nav/global_costmap", OccupancyGridMsg, timeout=60, qos=LATCHED_QOS)
        assert (costmap.info.width, costmap.info.height) == (160, 120)
        path = probe.wait_for_message(topics.NAV_PATH, Path, timeout=60)
        pts = np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses])
        start = room.pose_at(0.0)[:2, 3]
        assert np.linalg.norm(pts[0] - start) < 0.1 and np.linalg.norm(pts[-1] - goal) < 1e-6
        dense = np.concatenate([np.linspace(a, b, 40) for a, b in zip(pts, pts[1:])])
        for box in room.boxes:   # never inside a box grown by the robot radius
            inside = ((dense[:, 0] > box.lo[0] - 0.3) & (dense[:, 0] < box.hi[0] + 0.3)
                      & (dense[:, 1] > box.lo[1] - 0.3) & (dense[:, 1] < box.hi[1] + 0.3))
            assert not inside.any()
        # the walker stands at the start facing along the room: the hint sets off along the path,
        # turning towards it (the velocity window allows v ≥ 0 only, so v > 0 is what says "go")
        hint = probe.wait_for_message("/nav/cmd_vel_hint", Twist)
        forward = room.pose_at(0.0)[:2, 2] / np.linalg.norm(room.pose_at(0.0)[:2, 2])   # the camera's z axis
        along = np.cumsum(np.r_[0.0, np.linalg.norm(np.diff(dense, axis=0), axis=1)])
        ahead = dense[np.searchsorted(along, 1.0)] - pts[0]                               # 1 m along the path
        bearing = np.degrees(np.arctan2(forward[0] * ahead[1] - forward[1] * ahead[0], forward @ ahead))
        print(f"hint v {hint.linear.x:.3f} m/s, w {hint.angular.z:.3f} rad/s; the path 1 m ahead at {bearing:.1f}°")
        assert hint.linear.x > 0.0
        if abs(bearing) > 5.0:
            assert np.sign(hint.angular.z) == np.sign(bearing)
        # inflated costs, not the raw map: obstacle cells, the inscribed ring and graded costs
        static = np.array(costmap.data, np.int8)
        assert {100, 99}.issubset(set(static.tolist())) and ((static > 0) & (static < 99)).any()
        live = probe.wait_for_message(topics.NAV_OBSTACLE_LAYER, OccupancyGridMsg, timeout=60,
                                      predicate=lambda m: 100 in m.data)
        values = np.array(live.data, np.int8)
        assert (values == 0).any() and (values == -1).any()            # seen free, never seen
        combined = probe.wait_for_message(topics.NAV_COSTMAP, OccupancyGridMsg, timeout=60)
        assert (combined.info.width, combined.info.height) == (160, 120)
        guidance = probe.wait_for_message(topics.NAV_GUIDANCE, NavGuidance, timeout=30, predicate=lambda m: m.has_path)
        assert guidance.has_waypoint and guidance.header.frame_id == "map"

    def test_without_a_path_an_empty_path_replaces_the_old_one(self, room_graph, probe):
        g = room_graph.graph
        probe.wait_for_message(topics.NAV_PATH, Path, timeout=90, predicate=lambda m: len(m.poses) >= 2)
        [(_, ok, _)] = probe.set_params("planner", {"goal": [30.0, 1.5]})     # off the map
        assert ok
        probe.wait_for_message(topics.NAV_PATH, Path, timeout=30, predicate=lambda m: len(m.poses) == 0)
        g.wait_for_output(r"no path to the goal: goal \(30\.00, 1\.50\) is outside the map")


def test_planner_without_map_fails_with_one_line(graph):
    g = graph({"launch": {"nodes": [{"kind": "planner"}]}, "planner": {"ros__parameters": {"goal": [1.0, 1.0]}}})
    g.wait_for_output(r"configuration error: give exactly one of 'map' \(map_server YAML\) or 'world'")
    g.proc.wait(timeout=30)
    assert g.stop() == 1
    assert "Traceback" not in g.output


def test_planner_in_the_office_world_guides_to_the_bin(graph, probe):
    """The paper's navigation experiment: building map from the world's structure, named goal."""
    graph({"launch": {"nodes": [{"kind": "sim"}, {"kind": "planner"}]},
           "sim": {"ros__parameters": {"world": "office", "rate": 10.0}},
           "planner": {"ros__parameters": {"world": "office", "goal_name": "bin"}}})
    path = probe.wait_for_message(topics.NAV_PATH, Path, timeout=90)
    pts = np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses])
    assert np.linalg.norm(pts[0] - [1.0, 6.0]) < 0.3          # the avatar's spawn
    assert np.linalg.norm(pts[-1] - [19.0, 11.0]) < 1e-6       # the bin goal
    assert len(pts) >= 3                                       # it has to go around walls


def test_unknown_goal_name_is_a_one_line_error(graph):
    g = graph({"launch": {"nodes": [{"kind": "planner"}]},
               "planner": {"ros__parameters": {"world": "office", "goal_name": "fridge"}}})
    g.wait_for_output(r"goal_name 'fridge' is not a goal of the world; goals: bin")
    g.proc.wait(timeout=30)
    assert g.stop() == 1


def test_path_overlay_highlights_the_path_in_the_phosphenes(graph, probe, tmp_path):
    from raspv_msgs.msg import PhospheneFrame

    room = SyntheticRoom(CameraIntrinsics.from_hfov(64, 48, 60.0))
    save_map(room_map(room), tmp_path / "room.yaml")
    graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "planner"}, {"kind": "spv"}]},
           "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120, "walk_speed": 0.0}},
           "planner": {"ros__parameters": {"map": str(tmp_path / "room.yaml"), "goal": [1.6, 2.6]}},
           "spv": {"ros__parameters": {"device": "optimist", "mode": "depth", "overlays": ["path"],
                                       "temporal": False, "width": 200}}})
    # the walker at (1.6, 0) looks along +y; the goal is straight ahead, so the path is in view
    # (a frame with the overlay on: on a loaded machine the path can go stale for a moment, and
    # the spv node then drops the overlay, as it should)
    frame = probe.wait_for_message(topics.SPV_FRAME, PhospheneFrame, timeout=90,
                                   predicate=lambda f: list(f.overlays) == ["path"] and max(f.levels, default=0) == 7)
    levels = np.frombuffer(bytes(frame.levels), np.uint8)
    lit = levels == 7
    assert 5 < lit.sum() < 0.3 * len(levels)        # a band of phosphenes, not the whole field
    assert levels[~lit].max() <= 4                   # the rest dimmed ×0.5 (depth levels ≤ 7 → ≤ 4)


def test_a_slam_maps_stored_alignment_places_the_pose_frame_on_the_building_map(graph, probe, tmp_path):
    """slam_map: the planner reads B ← M from the map folder (as `raspv slam align` writes it) and
    publishes the building's costmap in the pose source's frame: its origin is M ← B applied to
    the building's origin."""
    room = SyntheticRoom(CameraIntrinsics.from_hfov(64, 48, 60.0))
    grid = room_map(room)
    save_map(grid, tmp_path / "room.yaml")
    slam_map = tmp_path / "maps" / "room_slam"
    slam_map.mkdir(parents=True)
    (slam_map / "map.yaml").write_text("format: raspv-slam-map\nversion: 1\n")
    (slam_map / "building_alignment.yaml").write_text(
        f"building_map: {tmp_path / 'room.yaml'}\nbuilding_map_sha256: ''\n"
        "building_from_map: {x: 0.5, y: -0.25, yaw_deg: 30.0, score: 0.9, matched: 0.8}\n")
    graph({"launch": {"nodes": [{"kind": "synthetic", "name": "cam"}, {"kind": "planner"}]},
           "cam": {"ros__parameters": {"rate": 10.0, "width": 160, "height": 120, "walk_speed": 0.0}},
           "planner": {"ros__parameters": {"map": str(tmp_path / "room.yaml"), "goal": [3.2, 1.5],
                                           "slam_map": str(slam_map)}}})
    costmap = probe.wait_for_message("/nav/global_costmap", OccupancyGridMsg, timeout=60, qos=LATCHED_QOS)
    yaw = np.radians(30.0)
    R = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    expected = R.T @ (np.array(grid.origin[:2]) - [0.5, -0.25])            # M ← B of the building's origin
    origin = costmap.info.origin
    assert np.allclose([origin.position.x, origin.position.y], expected, atol=1e-6)
    assert abs(2 * np.degrees(np.arctan2(origin.orientation.z, origin.orientation.w)) + 30.0) < 1e-3
