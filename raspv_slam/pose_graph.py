"""Pose-graph optimisation of keyframe poses with GTSAM (no ROS).

Nodes: keyframe poses S ← K (``gtsam.Pose3``). Factors: one ``BetweenFactorPose3`` per edge
(a ← b measured by registration) with a diagonal noise model from the config (rotation σ,
translation σ: the spread of a registration between keyframes); the first keyframe is held by a
tight prior (the gauge). A *local* optimisation (``held``: the keyframes around a window, held
at their poses by the same tight priors) moves only the window's keyframes: its cost does not grow
with the map (the loop closer's per-keyframe step, :mod:`loop_closing`).

Loop and covisibility edges passed geometric verification, but a wrong one would bend the whole
map, and a robust kernel (Huber, Cauchy) also holds back a *right* loop edge that closes a large
drift. So when the graph has such edges it is solved with graduated non-convexity (GTSAM's
``GncLMOptimizer``, truncated least squares; Yang et al., RA-L 2020): the odometry chain and the
prior are known inliers; every other edge ends either fully used or rejected (residual beyond
the χ² 99 % bound of its noise model). Without them, plain Levenberg-Marquardt.

GTSAM's Python calls hold the interpreter lock for the whole optimisation (measured: a 200-node
graph stalled another thread by up to 0.6 s on a loaded machine), so the loop closer runs it in
a process of its own (:class:`PoseGraphProcess`): tracking never waits for it.
"""
from __future__ import annotations

import math
import multiprocessing
import signal
from typing import TYPE_CHECKING

import numpy as np

from raspv_slam.config import SlamConfig

if TYPE_CHECKING:
    from raspv_slam.slam_map import Edge

PRIOR_SIGMA = 1e-6
INLIER_PROBABILITY = 0.99
EDGE_KINDS = ("odometry", "covisibility", "loop")


def optimise(poses: dict[int, np.ndarray], edges: list[Edge], config: SlamConfig, fixed: int | None = None,
             solver: "PoseGraphProcess | None" = None,
             held: set[int] | None = None) -> tuple[dict[int, np.ndarray], list[Edge]]:
    """(optimised poses (same keys as ``poses``), the edges judged outliers). Edges naming
    unknown keyframes, or only keyframes that are held, are skipped. ``fixed``: the gauge
    (default the smallest id); ``held``: keyframes kept at their poses (a local optimisation;
    default just the gauge). ``solver``: solve in that process instead of this one."""
    if not poses:
        return {}, []
    ids = sorted(poses)
    held = {min(poses) if fixed is None else fixed} if not held else set(held)
    used = [e for e in edges if e.a in poses and e.b in poses and e.a != e.b
            and not (e.a in held and e.b in held)]
    problem = (np.array(ids, np.int64), np.array([poses[k] for k in ids], np.float64).reshape(-1, 4, 4),
               np.array([e.a for e in used], np.int64), np.array([e.b for e in used], np.int64),
               np.array([e.a_from_b for e in used], np.float64).reshape(-1, 4, 4),
               np.array([EDGE_KINDS.index(e.kind) for e in used], np.int8),
               math.radians(config.edge_sigma_rotation_deg), config.edge_sigma_translation,
               np.array(sorted(held), np.int64))
    solved, outlier = solver.solve(problem) if solver is not None else solve(*problem)
    return {k: solved[i] for i, k in enumerate(ids)}, [e for e, out in zip(used, outlier) if out]


def solve(ids, poses, a, b, a_from_b, kinds, sigma_rotation, sigma_translation, held,
          max_iterations: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """The optimisation on plain arrays: (poses (N, 4, 4) in the order of ``ids``, outlier flag per
    edge); ``held``: ids kept at their poses by tight priors (at least the gauge)."""
    import gtsam

    graph = gtsam.NonlinearFactorGraph()
    initial = gtsam.Values()
    for k, T in zip(ids, poses):
        initial.insert(int(k), gtsam.Pose3(T))
    index = {int(k): i for i, k in enumerate(ids)}
    prior = gtsam.noiseModel.Isotropic.Sigma(6, PRIOR_SIGMA)
    for k in np.atleast_1d(held):
        graph.add(gtsam.PriorFactorPose3(int(k), gtsam.Pose3(poses[index[int(k)]]), prior))
    priors = graph.size()
    r, t = sigma_rotation, sigma_translation
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([r, r, r, t, t, t]))
    known_inliers = list(range(priors))
    for ea, eb, T, kind in zip(a, b, a_from_b, kinds):
        if EDGE_KINDS[kind] == "odometry":
            known_inliers.append(graph.size())
        graph.add(gtsam.BetweenFactorPose3(int(ea), int(eb), gtsam.Pose3(T), noise))
    lm = gtsam.LevenbergMarquardtParams()
    lm.setMaxIterations(max_iterations)
    outlier = np.zeros(len(a), bool)
    if len(known_inliers) == graph.size():
        result = gtsam.LevenbergMarquardtOptimizer(graph, initial, lm).optimize()
    else:
        params = gtsam.GncLMParams(lm)
        params.setLossType(gtsam.GncLossType.TLS)
        params.setKnownInliers(known_inliers)
        optimizer = gtsam.GncLMOptimizer(graph, initial, params)
        optimizer.setInlierCostThresholdsAtProbability(INLIER_PROBABILITY)
        result = optimizer.optimize()
        outlier = np.asarray(optimizer.getWeights())[priors:] < 0.5
    return np.array([result.atPose3(int(k)).matrix() for k in ids]).reshape(-1, 4, 4), outlier


class PoseGraphProcess:
    """:func:`solve` in a child process (started by :meth:`start` or on first use, stopped by
    :meth:`close`). The child imports GTSAM as it starts: a new interpreter importing numpy and
    GTSAM takes about a second on an idle machine and several under load, which the first
    optimisation waited for when the process was started by it (the first loop correction of a
    run landed seconds late: 8-14 s on the node's pan test under load 12)."""

    def __init__(self) -> None:
        self._conn = None
        self._process = None

    def start(self) -> None:
        """Start the child now (it gets ready while the caller goes on); no-op when running."""
        if self._process is None:
            ctx = multiprocessing.get_context("spawn")       # no fork of a process with threads
            self._conn, child = ctx.Pipe()
            self._process = ctx.Process(target=_serve, args=(child,), name="slam-pose-graph", daemon=True)
            self._process.start()
            child.close()

    def solve(self, problem: tuple) -> tuple[np.ndarray, np.ndarray]:
        self.start()
        self._conn.send(problem)
        try:
            ok, payload = self._conn.recv()
        except EOFError:
            raise RuntimeError(f"the pose-graph process died (exit code {self._process.exitcode})") from None
        if not ok:
            raise RuntimeError(f"pose-graph optimisation failed: {payload}")
        return payload

    def close(self) -> None:
        if self._process is not None:
            try:
                self._conn.send(None)
            except (BrokenPipeError, OSError):
                pass
            self._process.join(timeout=5)
            if self._process.is_alive():
                self._process.kill()
            self._conn.close()
            self._process = None


def _serve(conn) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)       # the parent stops it (Ctrl-C reaches the whole group)
    import gtsam  # noqa: F401  (ready before the first problem comes)
    while True:
        try:
            problem = conn.recv()
        except EOFError:
            return
        if problem is None:
            return
        try:
            conn.send((True, solve(*problem)))
        except RuntimeError as exc:                      # GTSAM's errors (indeterminant system, …)
            conn.send((False, str(exc).splitlines()[0] if str(exc) else type(exc).__name__))
