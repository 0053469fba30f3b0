"""A population of virtual patients: each subject number draws its own ability (no rclpy).

Virtual subject N's ability is drawn once from ``numpy.random.default_rng([POPULATION_SEED, N])``
— the same N always gets the same subject, on every machine — around the defaults of the
`subject` node, log-normally (every value stays positive; the spread factors below are the
log-normal sigmas, chosen to give plausible ranges, not fitted to people):

=====================  =======================================  ==========  ===============
ability                 meaning                                  median      sigma (log)
=====================  =======================================  ==========  ===============
``max_linear``          walking speed [m/s]                      0.6         0.15
``reaction_time_s``     frame → the command acting on it [s]     0.3         0.3
``min_brightness``      perceptual threshold (0..1)              0.15        0.3
``contrast_threshold``  what stands out from the floor (0..1)    0.12        0.3
``noise``               motor noise [rad/s]                      0.05        0.4
``perception_noise``    noise on each brightness read (0..1)     0.03        0.4
=====================  =======================================  ==========  ===============

Subject 0 is the population's median subject (no spread). Parameters given explicitly (a
sweep's ``subject_params``, ``raspv nodes subject``) override the drawn ones.
"""
from __future__ import annotations

import numpy as np

POPULATION_SEED = 20260523
ABILITY = {                         # name: (median, log-normal sigma, lower bound, upper bound)
    "max_linear": (0.6, 0.15, 0.3, 1.0),
    "reaction_time_s": (0.3, 0.3, 0.1, 0.9),
    "min_brightness": (0.15, 0.3, 0.05, 0.4),
    "contrast_threshold": (0.12, 0.3, 0.04, 0.3),
    "noise": (0.05, 0.4, 0.0, 0.3),
    "perception_noise": (0.03, 0.4, 0.0, 0.15),
}


def subject_ability(number: int, spread: float = 1.0) -> dict[str, float]:
    """Virtual subject ``number``'s ability (see the module docstring); ``spread`` scales every
    sigma (0: every subject is the median subject)."""
    if number < 0:
        raise ValueError(f"subject number must be >= 0, got {number}")
    rng = np.random.default_rng([POPULATION_SEED, int(number)])
    z = rng.standard_normal(len(ABILITY))            # drawn in a fixed order: one z per ability
    scale = 0.0 if number == 0 else float(spread)
    return {name: round(float(np.clip(median * np.exp(sigma * scale * zi), lo, hi)), 4)
            for (name, (median, sigma, lo, hi)), zi in zip(ABILITY.items(), z)}
