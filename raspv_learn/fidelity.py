"""The twin against the live renderer: the largest per-pixel difference over a run of frames,
as a fraction of the live image's peak (the issue's target: ≤ 1e-4).

Each frame draws random levels (30 % of the phosphenes off), runs them through the live
temporal model and renderer (:class:`PhospheneSimulator`, its float image before the uint8
conversion) and through the temporal twin and the twin built from the same simulator, so
rising, held and fading phosphenes are all compared. Used by ``tests/learn/test_twin.py`` and
``raspv bench twin``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from raspv_learn.temporal_twin import TemporalTwin
from raspv_learn.twin import PhospheneTwin
from raspv_spv.config import spv_config
from raspv_spv.simulator import PhospheneSimulator

TOLERANCE = 1e-4          # of the live image's peak, per pixel

# every sprite model; the widths put tissue models on a coarse grid (scale > 1) with and without
# a full-resolution part for small phosphenes: (what, device preset, width [px], defects)
SPRITE_CASES = [
    ("gaussian", "default", 200, {"dropout": 0.1, "noise_px": 1.0}),
    ("scoreboard retina, coarse + fine", "bva44", 160, {}),
    ("scoreboard cortex", "orion", 160, {"dropout": 0.1}),
    ("scoreboard cortex, coarse + fine", "neuralink", 160, {}),
    ("axon map, coarse", "argus_ii_axon", 240, {}),
    ("biphasic axon map (levelled)", "argus_ii_biphasic", 160, {}),
    ("dynaphos (levelled)", "orion_dynaphos", 160, {"dropout": 0.1}),
]


@dataclass
class Agreement:
    """Largest |twin − live| over the frames: as a fraction of each frame's peak, and of the
    node's uint8 image after rounding the twin (grey levels; the share of pixels that differ)."""

    max_error: float                # max over frames of max |twin − live float| / max(1, peak)
    max_rounded_diff: int           # max |round(twin) − live uint8| (grey levels)
    rounded_share: float            # largest share of pixels where round(twin) ≠ live uint8
    sim: PhospheneSimulator
    twin: PhospheneTwin


def agreement(device: str, width: int, frames: int = 14, seed: int = 1, **defects) -> Agreement:
    """Run ``frames`` frames of random levels through the live simulator and the twins."""
    sim = PhospheneSimulator(spv_config(device, width=width, temporal=True, **defects))
    twin = PhospheneTwin(sim)
    temporal = TemporalTwin.from_config(sim.config)
    rng = np.random.default_rng(seed)
    state, worst, worst_rounded, worst_share = None, 0.0, 0, 0.0
    for _ in range(frames):
        levels = rng.integers(0, sim.num_levels, sim.count).astype(np.uint8)
        levels[rng.random(sim.count) < 0.3] = 0
        brightness = sim.brightness(levels)
        live = np.minimum(sim.render_float(brightness).astype(np.float64), 255.0)   # uint8 saturates at 255
        live_u8 = sim.render(brightness)
        live_u8 = live_u8[..., 1] if live_u8.ndim == 3 else live_u8
        amp = torch.from_numpy(levels.astype(np.float32) / (sim.num_levels - 1))[None, None]
        with torch.no_grad():
            b, pulse, state = temporal(amp, state)
            ours = twin(b[:, 0] * twin.visible, pulse[:, 0] if twin.levelled else None)[0].numpy() * 255.0
        worst = max(worst, float(np.abs(ours - live).max()) / max(1.0, float(live.max())))
        rounded = np.rint(ours)
        worst_rounded = max(worst_rounded, int(np.abs(rounded - live_u8).max()))
        worst_share = max(worst_share, float(np.mean(rounded != live_u8)))
    return Agreement(worst, worst_rounded, worst_share, sim, twin)
