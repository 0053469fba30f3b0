"""Pose-graph optimisation of keyframe poses with GTSAM (no ROS).

Nodes: keyframe poses S ← K (``gtsam.Pose3``). Factors: one ``BetweenFactorPose3`` per edge
(a ← b measured by registration) with a diagonal noise model from the config (rotation σ,
translation σ: the spread of a dense RGB-D registration between keyframes); loop edges get a
Huber kernel so that a wrong loop that passed verification pulls with bounded force; the
first keyframe is held by a tight prior (the gauge). Solved by Levenberg-Marquardt.
"""
from __future__ import annotations

import math

import numpy as np

from raspv_slam.config import SlamConfig
from raspv_slam.slam_map import Edge

PRIOR_SIGMA = 1e-6


def optimise(poses: dict[int, np.ndarray], edges: list[Edge], config: SlamConfig, fixed: int | None = None,
             max_iterations: int = 100) -> dict[int, np.ndarray]:
    """Optimised poses (same keys as ``poses``); edges naming unknown keyframes are skipped."""
    import gtsam

    if not poses:
        return {}
    fixed = min(poses) if fixed is None else fixed
    graph = gtsam.NonlinearFactorGraph()
    initial = gtsam.Values()
    for k, T in poses.items():
        initial.insert(k, gtsam.Pose3(np.asarray(T, dtype=np.float64)))
    graph.add(gtsam.PriorFactorPose3(fixed, gtsam.Pose3(np.asarray(poses[fixed], dtype=np.float64)),
                                     gtsam.noiseModel.Isotropic.Sigma(6, PRIOR_SIGMA)))
    r = math.radians(config.edge_sigma_rotation_deg)
    t = config.edge_sigma_translation
    gaussian = gtsam.noiseModel.Diagonal.Sigmas(np.array([r, r, r, t, t, t]))
    robust = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(config.loop_huber), gaussian)
    for e in edges:
        if e.a in poses and e.b in poses and e.a != e.b:
            graph.add(gtsam.BetweenFactorPose3(e.a, e.b, gtsam.Pose3(np.asarray(e.a_from_b, dtype=np.float64)),
                                               robust if e.kind == "loop" else gaussian))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    result = gtsam.LevenbergMarquardtOptimizer(graph, initial, params).optimize()
    return {k: result.atPose3(k).matrix() for k in poses}
