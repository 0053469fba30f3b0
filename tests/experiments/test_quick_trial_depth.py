"""Quick trials see the depth the protocol's simulator gives: with the sim node's ``depth_noise``
on, noisy depth with holes, as in the graph (before, quick sweeps ignored it: always noise-free)."""
from __future__ import annotations

import numpy as np

from raspv_experiments.policies import PolicyConfig, WanderAvoid
from raspv_experiments.quick_trial import quick_trial

from .conftest import REPO

HALLWAY = str(REPO / "experiments" / "worlds" / "hallway.yaml")
SPV = {"device": "argus_ii", "mode": "depth", "temporal": False, "max_depth": 3.0}


def seen(sim_params):
    """The brightness of every frame a patient saw, standing still for 1 s."""
    frames = []

    class Watcher(WanderAvoid):
        def decide(self, b):
            frames.append(b.copy())
            return 0.0, 0.0

    quick_trial(HALLWAY, (1.0, 2.1, 0.0), (8.6, 1.5, 0.8), 1.0, spv=SPV, policy=Watcher, sim_params=sim_params,
                config=PolicyConfig(seed=1, reaction_time_s=0.0, noise=0.0))
    return np.array(frames)


def test_depth_noise_of_the_protocols_simulator_reaches_quick_trials():
    clean, default = seen({"depth_noise": False}), seen(None)
    assert np.array_equal(clean, default) and np.ptp(clean, axis=0).max() == 0.0       # noise-free: still frames equal
    noisy = seen({"depth_noise": True, "seed": 3})
    assert noisy.shape == clean.shape
    assert np.ptp(noisy, axis=0).max() > 0.0                  # the sensor's noise changes still frames
    assert 0.0 < np.abs(noisy - clean).mean() < 0.2           # near the clean view, not another view
    assert np.array_equal(noisy, seen({"depth_noise": True, "seed": 3}))      # seeded
