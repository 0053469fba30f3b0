"""The pose graph (GTSAM) pulls a drifted loop closed: a square walk whose odometry edges carry a
small systematic turn error ends far from its start; one loop edge with the true relative pose
brings every keyframe back near the ground truth. A wrong loop edge is rejected (graduated
non-convexity) while the right one is kept."""
import math

import numpy as np

from raspv_slam.config import SlamConfig
from raspv_slam.pose_graph import optimise
from raspv_slam.se3 import inverse
from raspv_slam.slam_map import Edge

from .conftest import motion_error


def yaw(deg: float, x: float = 0.0, y: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = (x, y)
    return T


def square_walk(n_side: int = 5, side: float = 4.0):
    """Ground-truth poses walking a square (turning 90° at each corner), back at the start."""
    poses, T = [], np.eye(4)
    for corner in range(4):
        for _ in range(n_side):
            poses.append(T.copy())
            T = T @ yaw(0.0, side / n_side)
        T = T @ yaw(90.0)
    return poses


def drifted(truth, bias_deg: float):
    edges, poses = [], [truth[0]]
    for i in range(1, len(truth)):
        measured = inverse(truth[i - 1]) @ truth[i] @ yaw(bias_deg)        # each step turns a little too much
        edges.append(Edge(i - 1, i, measured, "odometry"))
        poses.append(poses[-1] @ measured)
    return edges, {i: p for i, p in enumerate(poses)}


def test_a_loop_edge_pulls_a_drifted_square_closed():
    truth = square_walk()
    edges, poses = drifted(truth, 0.3)                   # within the edges' noise model (σ 0.5°)
    last = len(truth) - 1
    before = max(motion_error(truth[i], poses[i])[0] for i in poses)
    assert before > 0.1                                  # 6° of accumulated turn: decimetres off
    loop = Edge(last, 0, inverse(truth[last]) @ truth[0], "loop")
    result, outliers = optimise(poses, edges + [loop], SlamConfig(), fixed=0)
    assert outliers == []                                # a right loop edge is kept, however large the drift
    after = max(motion_error(truth[i], result[i])[0] for i in result)
    assert after < 0.1 * before, (before, after)
    np.testing.assert_allclose(result[0], truth[0], atol=1e-6)            # the gauge stays put


def test_a_wrong_loop_edge_is_rejected_and_the_right_ones_kept():
    truth = square_walk()
    edges, poses = drifted(truth, 0.3)
    last = len(truth) - 1
    right = Edge(last, 0, inverse(truth[last]) @ truth[0], "loop")
    wrong = Edge(10, 0, yaw(40.0, 1.0, 1.0), "loop")     # a false place match that passed verification
    result, outliers = optimise(poses, edges + [right, wrong], SlamConfig(), fixed=0)
    assert outliers == [wrong]
    assert max(motion_error(truth[i], result[i])[0] for i in result) < 0.05
    # the same wrong edge as an odometry edge (a known inlier) bends the map by metres
    bent, _ = optimise(poses, edges + [right, Edge(10, 0, wrong.a_from_b, "odometry")], SlamConfig(), fixed=0)
    assert max(motion_error(truth[i], bent[i])[0] for i in bent) > 0.5


def test_a_keyframe_added_after_a_loop_correction_lands_on_its_corrected_parent():
    """The tracker reads its reference's pose, then adds a keyframe; the background loop closer
    may correct the map in between. The new keyframe is placed on its parent as the map holds it
    at insertion (before: at the stale absolute pose, left behind by the correction); without a
    correction in between, the pose given is kept."""
    from raspv_slam.config import SlamConfig
    from raspv_slam.keyframe import Keyframe
    from raspv_slam.features import Features
    from raspv_slam.se3 import inverse
    from raspv_slam.slam_map import SlamMap

    from .conftest import K, pose

    def kf(i):
        return Keyframe(i, float(i), Features(np.zeros((0, 2)), np.zeros((0, 32), np.uint8), np.zeros((0, 3)),
                                              np.zeros(0)), np.zeros(1, np.uint8), np.zeros(1, np.uint8))
    m = SlamMap(K, SlamConfig())
    step = inverse(pose(0, 0, 0)) @ pose(0.5, 0.0, 10.0)
    m.add_keyframe(kf(0), np.eye(4))
    m.add_keyframe(kf(1), step, 0, step)
    seen = m.pose(1)                                           # what the tracker read before the correction
    stale = seen @ step
    correction = inverse(pose(0, 0, 0)) @ pose(0.0, 0.2, 5.0, z=1.7)
    m.apply_correction({0: correction, 1: correction @ step}, closed_loop=True)
    m.add_keyframe(kf(2), stale, 1, step, parent_pose_seen=seen)
    np.testing.assert_allclose(m.pose(2), m.pose(1) @ step, atol=1e-12)
    assert not np.allclose(m.pose(2), stale, atol=1e-3)
    np.testing.assert_allclose(m.relative(1, 2), step, atol=1e-12)
    np.testing.assert_allclose(m.relative(2, 0), inverse(m.pose(2)) @ m.pose(0), atol=1e-12)
    m.add_keyframe(kf(3), stale, transient=True)               # transient keyframes keep the pose given
    np.testing.assert_allclose(m.pose(3), stale)
    m.add_keyframe(kf(4), m.pose(2) @ step @ step, 2, step, parent_pose_seen=m.pose(2))   # no correction since
    np.testing.assert_allclose(m.pose(4), m.pose(2) @ step @ step, atol=1e-12)


def test_keyframes_chained_on_their_parents_stay_rigid():
    """The tracker places each keyframe on its parent as the map holds it (parent_pose_seen);
    the composition with the parent's inverse grew round-off threefold per keyframe, and a
    simulator walk's keyframe poses reached 1e11 after 35 keyframes without a correction."""
    from raspv_slam.features import Features
    from raspv_slam.keyframe import Keyframe
    from raspv_slam.slam_map import SlamMap

    from .conftest import K, pose

    def kf(i):
        return Keyframe(i, float(i), Features(np.zeros((0, 2)), np.zeros((0, 32), np.uint8), np.zeros((0, 3)),
                                              np.zeros(0)), np.zeros(1, np.uint8), np.zeros(1, np.uint8))
    m = SlamMap(K, SlamConfig())
    step = inverse(pose(0, 0, 0)) @ pose(0.2, 0.05, 7.0, z=0.01)
    m.add_keyframe(kf(0), pose(1.0, 2.0, 33.0))
    expected = m.pose(0)
    for i in range(1, 80):
        seen = m.pose(i - 1)
        m.add_keyframe(kf(i), seen @ step, i - 1, step, parent_pose_seen=seen)
        expected = expected @ step
    R = m.pose(79)[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(m.pose(79), expected, atol=1e-9)


def test_the_pose_graph_process_is_started_ahead_of_its_first_problem():
    """The loop closer starts the solver's process when its thread starts, so the first loop
    correction does not wait for a new interpreter to import GTSAM (seconds under load)."""
    from raspv_slam.pose_graph import PoseGraphProcess

    truth = square_walk(n_side=2)
    edges, poses = drifted(truth, 1.0)
    solver = PoseGraphProcess()
    try:
        solver.start()
        assert solver._process is not None and solver._process.is_alive()
        started = solver._process.pid
        solver.start()                                       # idempotent
        optimised, outliers = optimise(poses, edges, SlamConfig(), fixed=0, solver=solver)
        assert solver._process.pid == started and not outliers and set(optimised) == set(poses)
    finally:
        solver.close()
    assert solver._process is None
