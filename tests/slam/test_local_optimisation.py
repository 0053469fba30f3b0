"""The loop closer's per-keyframe optimisation is local (issue 32: on a 10-minute walk through new
places the whole-graph optimisation per keyframe left it thousands of keyframes behind): the
sub-map's last keyframes move, their neighbours are held, so the work per keyframe does not grow
with the map; a loop edge — or an edge out of the window that disagrees with the map — still
optimises the whole sub-map, and a wrong edge is still rejected either way."""
import numpy as np

from raspv_slam.config import SlamConfig
from raspv_slam.features import Features
from raspv_slam.keyframe import Keyframe
from raspv_slam.loop_closing import LoopCloser
from raspv_slam.pose_graph import optimise
from raspv_slam.se3 import inverse
from raspv_slam.slam_map import Edge, SlamMap

from .conftest import K, motion_error
from .test_pose_graph import drifted, square_walk, yaw

WINDOW = 12


def _keyframe(i: int) -> Keyframe:
    return Keyframe(i, float(i), Features(np.zeros((0, 2)), np.zeros((0, 32), np.uint8), np.zeros((0, 3)),
                                          np.zeros(0)), np.zeros(1, np.uint8), np.zeros(1, np.uint8))


def _closer(truth, bias_deg: float = 0.3):
    """A loop closer (no registration needed) on a map of the drifted walk's keyframes."""
    config = SlamConfig(background=False, local_window_keyframes=WINDOW)
    m = SlamMap(K, config)
    edges, poses = drifted(truth, bias_deg)
    m.add_keyframe(_keyframe(0), poses[0])
    for e in edges:
        m.add_keyframe(_keyframe(e.b), poses[e.b], e.a, e.a_from_b)
    return LoopCloser(m, None, None, config), m


def test_a_local_optimisation_holds_its_neighbours_and_rejects_a_wrong_edge():
    truth = square_walk()
    edges, poses = drifted(truth, 0.3)
    held = set(range(10))
    right = Edge(15, 19, inverse(truth[15]) @ truth[19], "covisibility")
    wrong = Edge(14, 19, yaw(40.0, 1.0, 1.0), "covisibility")
    result, outliers = optimise(poses, edges + [right, wrong], SlamConfig(), held=held)
    assert outliers == [wrong]
    for k in held:
        np.testing.assert_allclose(result[k], poses[k], atol=1e-6)


def test_the_work_per_keyframe_does_not_grow_with_the_map():
    truth = square_walk(n_side=30)                        # 120 keyframes
    closer, m = _closer(truth)
    moved = []
    for kf_id in (40, 80, 119):                            # a consistent covisibility edge to a recent keyframe
        edge = Edge(kf_id - 3, kf_id, m.relative(kf_id - 3, kf_id), "covisibility")
        m.add_edge(edge)
        moved.append(closer.optimise_after(kf_id, False, [edge]))
    assert moved == [WINDOW] * 3
    assert closer.whole_graph_optimisations == 0
    old = m.pose(5)
    far = Edge(5, 119, m.relative(5, 119), "covisibility")    # out of the window, agreeing with the map
    m.add_edge(far)
    assert closer.optimise_after(119, False, [far]) == WINDOW
    np.testing.assert_allclose(m.pose(5), old, atol=1e-6)     # held


def test_a_loop_edge_optimises_the_whole_map_and_a_wrong_one_is_rejected():
    truth = square_walk(n_side=30)
    closer, m = _closer(truth, bias_deg=0.05)            # 6° of accumulated turn, as the 20-keyframe square's
    last = len(truth) - 1
    before = max(motion_error(truth[k], m.pose(k))[0] for k in range(len(truth)))
    right = Edge(last, 0, inverse(truth[last]) @ truth[0], "loop")
    wrong = Edge(60, last, yaw(40.0, 1.0, 1.0), "loop")
    m.add_edge(right)
    m.add_edge(wrong)
    assert closer.optimise_after(last, True, []) == len(truth) - 1
    assert closer.whole_graph_for_loops == 1
    assert closer.rejected == [wrong] and wrong not in m.edges
    after = max(motion_error(truth[k], m.pose(k))[0] for k in range(len(truth)))
    assert after < 0.1 * before, (before, after)


def test_an_edge_out_of_the_window_that_disagrees_closes_the_loop_over_the_whole_map():
    """A loop closed by covisibility (the drift small enough for the old place to be found by its
    pose) must spread along the loop, not bend the window."""
    truth = square_walk(n_side=30)
    closer, m = _closer(truth, bias_deg=0.05)
    last = len(truth) - 1
    edge = Edge(2, last, inverse(truth[2]) @ truth[last], "covisibility")
    assert motion_error(m.pose(2) @ edge.a_from_b, m.pose(last))[0] > 0.02
    m.add_edge(edge)
    assert closer.optimise_after(last, False, [edge]) == len(truth) - 1
    assert closer.whole_graph_optimisations == 1 and closer.whole_graph_for_loops == 0
    assert max(motion_error(truth[k], m.pose(k))[0] for k in range(len(truth))) < 0.02


def test_keyframes_made_after_the_one_optimised_follow_it_and_the_first_stays():
    """A loop closer behind tracking optimises keyframe 3 while 4 and 5 exist: they move with their
    parent, and the map's first keyframe stays (held, they had become the gauge and moved it)."""
    truth = square_walk(n_side=2)[:6]
    closer, m = _closer(truth, bias_deg=0.3)
    before = m.poses()
    edge = Edge(0, 3, inverse(truth[0]) @ truth[3], "covisibility")       # the truth: disagrees with the drift
    m.add_edge(edge)
    closer.optimise_after(3, False, [edge])
    after = m.poses()
    np.testing.assert_allclose(after[0], before[0], atol=1e-6)
    assert motion_error(after[3], before[3])[1] > 0.1                     # the window moved
    for k in (4, 5):                                                       # rigidly with keyframe 3
        np.testing.assert_allclose(inverse(after[3]) @ after[k], inverse(before[3]) @ before[k], atol=1e-6)
