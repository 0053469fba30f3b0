"""Navigation on a replayed recording with a building map (the paper's Fig. 13 set-up).

No real recording with a building map exists here, so the recording is made in the simulator and
stripped of its pose: colour, depth and camera info only, stamped with a recording's clock
(2023). The graph is the replay graph (replay, scene, odometry) plus the planner on the office's
map; the map frame is placed in the odometry frame by ``map_from_odom``, the camera's start on
the map. The path must start where the camera really is and end at the goal, in the odometry
frame, stamped with bag time."""
from __future__ import annotations

import math

import numpy as np
import pytest
from nav_msgs.msg import Path as PathMsg

from raspv_bags.from_frames import RgbdBagWriter
from raspv_common import topics
from raspv_nav.motion import planar_pose, planar_transform
from raspv_nav.nav_msg import path_from_msg
from raspv_common.occupancy import save_map

pytestmark = [pytest.mark.integration, pytest.mark.slow]

BAG_T0 = 1_700_000_000.0          # a recording's clock, far from the test's wall clock
GOAL = (19.0, 11.0)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """1.5 s standing, then a 6 s walk east along the office corridor at 0.5 m/s, 10 frames/s,
    without poses; the office's structural map; the true camera poses by stamp."""
    from raspv_sim.occupancy_export import world_occupancy
    from raspv_sim.simulator import SimConfig, Simulation

    out = tmp_path_factory.mktemp("replay")
    truth = {}
    with Simulation("office", SimConfig(width=320, height=240)) as sim:
        save_map(world_occupancy(sim.world, 0.05, structure_only=True), out / "office.yaml")
        with RgbdBagWriter(out / "walk", with_pose=False) as bag:
            for i in range(75):                  # 1.5 s standing (as a recording starts), then walking
                sim.step(0.1 if i else 0.0, 0.5 if i >= 15 else 0.0, 0.0)
                frame = sim.render()
                stamp = BAG_T0 + 0.1 * i
                bag.add(stamp, frame.rgb, frame.depth, frame.intrinsics)
                truth[round(stamp, 3)] = frame.world_from_camera
    return out, truth


def test_a_replayed_recording_navigates_on_the_building_map(graph, probe, recording):
    out, truth = recording
    x0, y0, yaw0 = planar_pose(truth[round(BAG_T0, 3)], axis=2)       # the camera's start on the map
    graph({"launch": {"nodes": [{"kind": "replay"}, {"kind": "scene"}, {"kind": "odometry"}, {"kind": "planner"}]},
           "replay": {"ros__parameters": {"bag": str(out / "walk"), "wait_for_subscribers": 7, "delay": 1.0,
                                          "rate": 0.5}},       # half speed: odometry keeps up on a loaded machine
           "planner": {"ros__parameters": {"map": str(out / "office.yaml"), "goal": list(GOAL),
                                           "map_from_odom": [x0, y0, math.degrees(yaw0)],
                                           "pose_source": "camera", "replan_rate": 10.0}}})
    W_M = np.linalg.inv(planar_transform(x0, y0, yaw0))
    paths = probe.subscribe(topics.NAV_PATH, PathMsg)
    got = paths.wait(3, timeout=180, predicate=lambda m: len(m.poses) >= 2 and m.header.stamp.sec > BAG_T0 + 2)
    for msg in got:
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        assert BAG_T0 <= stamp <= BAG_T0 + 7.5                             # bag time, not the wall clock
        nearest = min(truth, key=lambda s: abs(s - stamp))
        true_map = truth[nearest][:2, 3]
        true_odom = W_M[:2, :2] @ true_map + W_M[:2, 3]
        path = path_from_msg(msg)[:, :2]
        assert msg.header.frame_id == "map"
        assert np.linalg.norm(path[0] - true_odom) < 0.25                   # starts where the camera is
        np.testing.assert_allclose(path[-1], W_M[:2, :2] @ GOAL + W_M[:2, 3], atol=1e-6)   # ends at the goal
        on_map = path @ W_M[:2, :2] + (-(W_M[:2, :2].T @ W_M[:2, 3]))     # back to the map frame
        assert (np.abs(on_map[:, 1] - 6.0) < 1.0).sum() >= 2                # along the corridor
