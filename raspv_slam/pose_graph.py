"""Pose-graph optimisation of keyframe poses with GTSAM (no ROS).

Nodes: keyframe poses S ← K (``gtsam.Pose3``). Factors: one ``BetweenFactorPose3`` per edge
(a ← b measured by registration) with a diagonal noise model from the config (rotation σ,
translation σ: the spread of a registration between keyframes); the first keyframe is held by a
tight prior (the gauge).

Loop and covisibility edges passed geometric verification, but a wrong one would bend the whole
map, and a robust kernel (Huber, Cauchy) also holds back a *right* loop edge that closes a large
drift. So when the graph has such edges it is solved with graduated non-convexity (GTSAM's
``GncLMOptimizer``, truncated least squares; Yang et al., RA-L 2020): the odometry chain and the
prior are known inliers; every other edge ends either fully used or rejected (residual beyond
the χ² 99 % bound of its noise model). Without them, plain Levenberg-Marquardt.
"""
from __future__ import annotations

import math

import numpy as np

from raspv_slam.config import SlamConfig
from raspv_slam.slam_map import Edge

PRIOR_SIGMA = 1e-6
INLIER_PROBABILITY = 0.99


def optimise(poses: dict[int, np.ndarray], edges: list[Edge], config: SlamConfig, fixed: int | None = None,
             max_iterations: int = 100) -> tuple[dict[int, np.ndarray], list[Edge]]:
    """(optimised poses (same keys as ``poses``), the edges judged outliers). Edges naming
    unknown keyframes are skipped."""
    import gtsam

    if not poses:
        return {}, []
    fixed = min(poses) if fixed is None else fixed
    graph = gtsam.NonlinearFactorGraph()
    initial = gtsam.Values()
    for k, T in poses.items():
        initial.insert(k, gtsam.Pose3(np.asarray(T, dtype=np.float64)))
    graph.add(gtsam.PriorFactorPose3(fixed, gtsam.Pose3(np.asarray(poses[fixed], dtype=np.float64)),
                                     gtsam.noiseModel.Isotropic.Sigma(6, PRIOR_SIGMA)))
    r = math.radians(config.edge_sigma_rotation_deg)
    t = config.edge_sigma_translation
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([r, r, r, t, t, t]))
    known_inliers = [0]
    used: list[Edge] = []
    for e in edges:
        if e.a in poses and e.b in poses and e.a != e.b:
            if e.kind == "odometry":
                known_inliers.append(graph.size())
            graph.add(gtsam.BetweenFactorPose3(e.a, e.b, gtsam.Pose3(np.asarray(e.a_from_b, dtype=np.float64)), noise))
            used.append(e)
    lm = gtsam.LevenbergMarquardtParams()
    lm.setMaxIterations(max_iterations)
    if len(known_inliers) == graph.size():
        result = gtsam.LevenbergMarquardtOptimizer(graph, initial, lm).optimize()
        return {k: result.atPose3(k).matrix() for k in poses}, []
    params = gtsam.GncLMParams(lm)
    params.setLossType(gtsam.GncLossType.TLS)
    params.setKnownInliers(known_inliers)
    optimizer = gtsam.GncLMOptimizer(graph, initial, params)
    optimizer.setInlierCostThresholdsAtProbability(INLIER_PROBABILITY)
    result = optimizer.optimize()
    weights = np.asarray(optimizer.getWeights())
    outliers = [e for i, e in enumerate(used, start=1) if weights[i] < 0.5]
    return {k: result.atPose3(k).matrix() for k in poses}, outliers
