"""The biphasic axon-map model (Granley & Beyeler 2021, IEEE EMBC) as pulse2percept 0.11's
``BiphasicAxonMapModel`` computes it (no ROS).

A biphasic pulse train of frequency f (Hz), amplitude a (multiples of the perceptual
threshold, xTh) and phase duration t (ms) scales the axon-map phosphene of
:mod:`raspv_spv.axon_map`:

- brightness F_bright = a2·ã + a3·f + a4,
- size ρ_eff = ρ·√F_size with F_size = max(a5·ã + a6, min_rho²/ρ²),
- streak length λ_eff = λ·√F_streak with F_streak = max(a9 − a7·t^a8, min_λ²/λ²),

where ã = a·(a1 + a0·t) is the amplitude corrected for the phase duration (pulse2percept's
Argus II refit of Horsager 2009). Coefficients: a0 = 2.095, a1 = 0.054326, a2 = 0.1492147,
a3 = 0.0163851, a4 = 0, a5 = 1.0812, a6 = −0.35338, a7 = 0.54, a8 = 0.21, a9 = 1.56,
min ρ = min λ = 10 µm.

In the simulator each level above 0 is one pulse amplitude (:func:`level_amplitudes_xth`), so
each electrode has one sprite per level (size, streak and brightness of that amplitude); the
display frame rate is the pulse frequency (one pulse per frame, as the temporal model).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from raspv_spv.axon_map import AxonSegments, axon_sprites


@dataclass(frozen=True)
class GranleyEffects:
    """Effect-model coefficients (pulse2percept 0.11 defaults)."""

    a0: float = 2.095
    a1: float = 0.054326
    a2: float = 0.1492147
    a3: float = 0.0163851
    a4: float = 0.0
    a5: float = 1.0812
    a6: float = -0.35338
    a7: float = 0.54
    a8: float = 0.21
    a9: float = 1.56
    min_rho_um: float = 10.0
    min_lambda_um: float = 10.0

    def scaled_amplitude(self, amp_xth, pdur_ms):
        return np.asarray(amp_xth, dtype=np.float64) * (self.a1 + self.a0 * pdur_ms)

    def brightness(self, freq_hz, amp_xth, pdur_ms):
        """F_bright (Granley 2021 eq. 4)."""
        return self.a2 * self.scaled_amplitude(amp_xth, pdur_ms) + self.a3 * freq_hz + self.a4

    def size(self, amp_xth, pdur_ms, rho_um):
        """F_size: ρ² is scaled by it."""
        return np.maximum(self.a5 * self.scaled_amplitude(amp_xth, pdur_ms) + self.a6, self.min_rho_um ** 2 / rho_um ** 2)

    def streak(self, pdur_ms, lambda_um):
        """F_streak: λ² is scaled by it."""
        return np.maximum(self.a9 - self.a7 * np.asarray(pdur_ms, dtype=np.float64) ** self.a8,
                          self.min_lambda_um ** 2 / lambda_um ** 2)


def level_amplitudes_xth(num_levels: int, max_amplitude_xth: float) -> np.ndarray:
    """Pulse amplitude (xTh) of levels 1 … N_L−1: level 1 at threshold (1 xTh), the top level at
    ``max_amplitude_xth``, linear in between."""
    n = num_levels - 1
    if n == 1:
        return np.array([float(max_amplitude_xth)])
    return 1.0 + (max_amplitude_xth - 1.0) * np.arange(n) / (n - 1)


def biphasic_axon_sprites(axons: AxonSegments, electrodes_um: np.ndarray, rho_um: float, axlambda_um: float,
                          amplitudes_xth: np.ndarray, freq_hz: float, pdur_ms: float,
                          effects: GranleyEffects = GranleyEffects(), min_weight: float = 1e-3) -> sp.csc_matrix:
    """Sparse (points, E·L) sprites, column e·L + l for electrode e driven at
    ``amplitudes_xth[l]``: F_bright · max_s sens(s)^(1/F_streak) · exp(−d²/(2ρ²F_size)).
    ``axons`` must have been built with ``axlambda_um`` (the base λ)."""
    electrodes_um = np.asarray(electrodes_um, dtype=np.float64).reshape(-1, 2)
    amps = np.asarray(amplitudes_xth, dtype=np.float64).ravel()
    n_el, n_lv = len(electrodes_um), len(amps)
    bright = effects.brightness(freq_hz, amps, pdur_ms)
    size = effects.size(amps, pdur_ms, rho_um)
    streak = float(effects.streak(pdur_ms, axlambda_um))
    per_level = np.ones((n_el, n_lv))
    return axon_sprites(axons, electrodes_um, per_level * rho_um * np.sqrt(size), per_level / streak,
                        per_level * bright, min_weight)
