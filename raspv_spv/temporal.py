"""Continuous temporal models of phosphene brightness driven by electrode current (no ROS).

Two linear–nonlinear cascades fitted on Argus I patients, integrated with forward Euler on a
fixed step ``dt`` exactly as pulse2percept 0.11 does (``Horsager2009Temporal``,
``Nanduri2012Temporal``), but vectorised over many stimuli at once (one row per stimulus):

Horsager et al. 2009 (IOVS 50:1483), current A(t) in µA, time in ms::

    r1 += dt/τ1 · (−A − r1)          fast response, driven by cathodic (negative) current
    ca += dt · max(A, 0)             charge accumulation (anodic phase)
    r2 += dt/τ2 · (ca − r2)
    r3  = max(r1 − ε/1000 · r2, 0)^β
    r4a, r4b, b: three leaky integrators with τ3; b is the brightness

Nanduri et al. 2012 (IOVS 53:205): same cascade with r1 driven by +A, no power law, and the
whole r3 trace scaled by g = asymptote/max(r3) · σ((max(r3) − shift)/slope) — max over the
simulated interval, so the response up to t depends on the stimulus up to the last output time.

ε is given per µs as in the papers and divided by 1000 for millisecond integration.
Stimuli are piecewise constant: each ``dt`` step uses the value of the latest breakpoint at or
before it (``current_on_grid``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def _leaky(x: np.ndarray, a: float) -> np.ndarray:
    """Forward-Euler leaky integrator r[n] = r[n−1] + a·(x[n] − r[n−1]), r[−1] = 0, along the last axis."""
    # imported here: scipy.signal takes ~0.8 s to import and is needed only to build a look-up
    # table (cached on disk), not to start a node that loads one
    from scipy.signal import lfilter

    return lfilter([a], [1.0, -(1.0 - a)], x, axis=-1)


def _check_step(dt: float, **taus: float) -> None:
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"time step dt must be a positive number of ms, got {dt}")
    for name, tau in taus.items():
        if not (math.isfinite(tau) and tau > 0):
            raise ValueError(f"{name} must be a positive time constant in ms, got {tau}")
        if dt >= tau:
            raise ValueError(f"time step dt={dt} ms must be smaller than {name}={tau} ms for a stable integration")


@dataclass(frozen=True)
class Horsager2009:
    """Horsager et al. 2009 cascade (pulse2percept defaults: threshold fit). Times in ms."""

    tau1: float = 0.42
    tau2: float = 45.25
    tau3: float = 26.25
    eps: float = 2.25     # per µs (the supra-threshold fit uses 8.73)
    beta: float = 3.43    # (the supra-threshold fit uses 0.83)
    dt: float = 0.005

    name = "horsager2009"

    def __post_init__(self) -> None:
        _check_step(self.dt, tau1=self.tau1, tau2=self.tau2, tau3=self.tau3)

    def response(self, current: np.ndarray) -> np.ndarray:
        """Brightness (…, T) for current samples (…, T) in µA, one sample per ``dt`` step."""
        amp = np.asarray(current, dtype=np.float64)
        r1 = _leaky(-amp, self.dt / self.tau1)
        ca = np.cumsum(np.maximum(amp, 0.0), axis=-1) * self.dt
        r2 = _leaky(ca, self.dt / self.tau2)
        r3 = np.maximum(r1 - (self.eps / 1000.0) * r2, 0.0)
        np.power(r3, self.beta, out=r3)
        a3 = self.dt / self.tau3
        return _leaky(_leaky(_leaky(r3, a3), a3), a3)


@dataclass(frozen=True)
class Nanduri2012:
    """Nanduri et al. 2012 cascade (pulse2percept defaults). Times in ms."""

    tau1: float = 0.42
    tau2: float = 45.25
    tau3: float = 26.25
    eps: float = 8.73      # per µs
    asymptote: float = 14.0
    slope: float = 3.0
    shift: float = 16.0
    scale_out: float = 1.0
    dt: float = 0.005

    name = "nanduri2012"

    def __post_init__(self) -> None:
        _check_step(self.dt, tau1=self.tau1, tau2=self.tau2, tau3=self.tau3)
        if self.slope <= 0:
            raise ValueError(f"slope must be positive, got {self.slope}")

    def response(self, current: np.ndarray) -> np.ndarray:
        """Brightness (…, T) for current samples (…, T) in µA, one sample per ``dt`` step."""
        amp = np.asarray(current, dtype=np.float64)
        r1 = _leaky(amp, self.dt / self.tau1)
        ca = np.cumsum(np.maximum(amp, 0.0), axis=-1) * self.dt
        r2 = _leaky(ca, self.dt / self.tau2)
        r3 = np.maximum(r1 - (self.eps / 1000.0) * r2, 0.0)
        peak = r3.max(axis=-1, keepdims=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            gain = self.asymptote / peak / (1.0 + np.exp(-(peak - self.shift) / self.slope))
        r3 *= np.where(peak > 0, gain, 0.0)
        a3 = self.dt / self.tau3
        return self.scale_out * _leaky(_leaky(_leaky(r3, a3), a3), a3)


TEMPORAL_MODELS = {"horsager2009": Horsager2009, "nanduri2012": Nanduri2012}


def temporal_model(name: str, dt: float = 0.005) -> Horsager2009 | Nanduri2012:
    """The continuous model called ``name`` with its published parameters."""
    if name not in TEMPORAL_MODELS:
        raise ValueError(f"unknown temporal model {name!r}; known: {', '.join(TEMPORAL_MODELS)}")
    return TEMPORAL_MODELS[name](dt=dt)


@dataclass(frozen=True)
class BiphasicPulse:
    """A charge-balanced biphasic current pulse: ``amplitude_ua`` µA for ``phase_ms`` in each
    phase, ``interphase_ms`` apart, cathodic (negative) phase first unless told otherwise."""

    amplitude_ua: float = 20.0
    phase_ms: float = 0.45
    interphase_ms: float = 0.0
    cathodic_first: bool = True

    def __post_init__(self) -> None:
        if not (math.isfinite(self.amplitude_ua) and self.amplitude_ua > 0):
            raise ValueError(f"pulse amplitude must be a positive number of µA, got {self.amplitude_ua}")
        if not (math.isfinite(self.phase_ms) and self.phase_ms > 0):
            raise ValueError(f"pulse phase duration must be positive [ms], got {self.phase_ms}")
        if not (math.isfinite(self.interphase_ms) and self.interphase_ms >= 0):
            raise ValueError(f"interphase gap must be >= 0 ms, got {self.interphase_ms}")

    @property
    def duration_ms(self) -> float:
        return 2 * self.phase_ms + self.interphase_ms


def pulse_train_breakpoints(onsets_ms: np.ndarray, pulse: BiphasicPulse) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints (times [ms], currents [µA]) of biphasic pulses starting at ``onsets_ms``;
    the current holds each value until the next breakpoint and ends at 0."""
    onsets = np.sort(np.asarray(onsets_ms, dtype=float).ravel())
    if onsets.size and np.any(np.diff(onsets) < pulse.duration_ms):
        raise ValueError(f"pulses overlap: onsets closer than the pulse duration {pulse.duration_ms} ms")
    first = -pulse.amplitude_ua if pulse.cathodic_first else pulse.amplitude_ua
    offs = np.array([0.0, pulse.phase_ms, pulse.phase_ms + pulse.interphase_ms, pulse.duration_ms])
    vals = np.array([first, 0.0, -first, 0.0])
    times = (onsets[:, None] + offs[None, :]).ravel()
    values = np.tile(vals, onsets.size)
    keep = np.ones(times.size, bool)
    keep[:-1] = times[:-1] < times[1:]          # no interphase gap: drop the zero-length step
    return times[keep], values[keep]


def current_on_grid(times_ms: np.ndarray, currents: np.ndarray, dt: float, n_steps: int) -> np.ndarray:
    """Sample a piecewise-constant stimulus at t = i·dt, i = 0 … n_steps−1 (0 before the first
    breakpoint). ``currents`` is (K,) or (S, K) for S stimuli sharing the breakpoints."""
    times = np.asarray(times_ms, dtype=float)
    cur = np.asarray(currents, dtype=float)
    if times.ndim != 1 or cur.shape[-1] != times.size:
        raise ValueError(f"breakpoints: {times.size} times but currents of shape {cur.shape}")
    if np.any(np.diff(times) < 0):
        raise ValueError("breakpoint times must be sorted")
    t = np.arange(n_steps) * dt
    idx = np.searchsorted(times, t + 1e-9 * dt, side="right") - 1
    padded = np.concatenate([np.zeros(cur.shape[:-1] + (1,)), cur], axis=-1)
    return padded[..., idx + 1]
