"""What one biphasic pulse does to the Horsager 2009 / Nanduri 2012 cascades (no ROS): tables
that let :mod:`raspv_spv.temporal_recursive` advance the models exactly over any interval.

Between pulses the current is 0 and every stage of the cascades is linear, so the state moves by
closed-form exponentials. Only during a pulse is the nonlinearity r3 = max(r1 − ε·r2, 0)^β
non-zero, and only for a short window after its onset (``window_ms`` = pulse + 20 τ1: r1 has
then decayed to e^−20 of its peak; for cathodic-first pulses in Horsager's model r3 is 0 from
the end of the pulse on). Over that window:

- r1(s) is the same for every pulse (the previous pulse's r1 has decayed: pulses must be at least
  a window apart);
- r2(s) = r2₀·v(s) + d·h(s) + q(s), with r2₀ the value at the onset, d = ca₀ − r2₀, and v, h, q
  known functions of the time s since the onset (q: the pulse's own charge);
- the three τ3 integrators turn r3 into the state x(s) = (x1, x2, x3) by the moments
  I_k(s) = ∫₀ˢ r3(u)·e^{u/τ3}·u^k du, k = 0, 1, 2.

So the state a pulse adds depends on one number, r2₀, plus a first-order term in d (ε·d·h(s)
stays below 10⁻³ µA: its square is far below 10⁻⁸ of the response). :func:`build_bursts` tabulates
x(s) on a grid of r2₀ and of s by quadrature on a fine grid (trapezoid, ~8 000 points per window,
every phase edge on the grid), and the derivative in d; Nanduri's model adds the peak of r3 for its
gain. Charge accumulation may recover with ``recovery_ms`` (ca leaks back; ∞: pulse2percept's
model, in which it never does). Times in ms, current in µA, charge in µA·ms.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raspv_spv.temporal import BiphasicPulse, Horsager2009, Nanduri2012

WINDOW_TAU1 = 20.0         # the burst window: the pulse plus this many τ1
GRID_R2 = 1024             # r2₀ grid points (linear interpolation: < 1e-6 of a burst)
GRID_S = 256               # window sample points of the partial bursts (x3 is smooth in s)
FINE_PER_PHASE = 512       # quadrature points per pulse phase (trapezoid error ~1e-6 of a burst)
FINE_TAIL = 2048           # quadrature points over the tail after the pulse (Nanduri's r1 decays there)


@dataclass(frozen=True)
class BurstTables:
    """Per-pulse effect of one model and pulse. ``full`` (G, 3) and ``full_d`` (G, 3): the
    integrators' state at the end of the window per r2₀ grid value and its derivative in d;
    ``partial``/``partial_d`` (S, G): x3 at ``s_grid`` inside the window; ``peak``/``peak_d``
    (G,): the largest r3 of the burst (Nanduri's gain); ``r2_step`` the r2₀ grid step;
    ``ca_after``/``r2_after``: ca and r2 the pulse itself leaves at the end of the window."""

    window_ms: float
    r2_step: float
    full: np.ndarray
    full_d: np.ndarray
    s_grid: np.ndarray
    partial: np.ndarray
    partial_d: np.ndarray
    peak: np.ndarray
    peak_d: np.ndarray
    ca_after: float
    r2_after: float


def charge_decay(k: float, tau2: float, t: float) -> tuple[float, float, float]:
    """Free evolution over ``t`` ms of (ca, r2) with ca leaking at rate ``k`` [1/ms] (0: never):
    ca ← a·ca, r2 ← b·r2 + c·ca. Returns (a, b, c)."""
    a = math.exp(-k * t)
    b = math.exp(-t / tau2)
    c = (a - b) / (1.0 - k * tau2)
    return a, b, c


def _segments(pulse: BiphasicPulse, window_ms: float) -> list[tuple[float, float, float]]:
    """(start, end, current) of the piecewise-constant current over the window."""
    first = -pulse.amplitude_ua if pulse.cathodic_first else pulse.amplitude_ua
    p, g = pulse.phase_ms, pulse.interphase_ms
    segs = [(0.0, p, first)]
    if g > 0:
        segs.append((p, p + g, 0.0))
    segs += [(p + g, 2 * p + g, -first), (2 * p + g, window_ms, 0.0)]
    return segs


def fine_grid(pulse: BiphasicPulse, window_ms: float) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature points u [ms] over the window (every edge on the grid) and the current A(u) on
    each interval [u_i, u_i+1) (len − 1)."""
    pts, cur = [], []
    step = pulse.phase_ms / FINE_PER_PHASE
    for start, end, amp in _segments(pulse, window_ms):
        if end <= start:
            continue
        n = FINE_TAIL if start >= pulse.duration_ms else max(8, int(math.ceil((end - start) / step)))
        pts.append(np.linspace(start, end, n + 1)[:-1])
        cur.append(np.full(n, amp))
    return np.concatenate(pts + [np.array([window_ms])]), np.concatenate(cur)


def _r1(u: np.ndarray, current: np.ndarray, tau1: float, sign: float) -> np.ndarray:
    """r1 at the grid points, exact for piecewise-constant current (r1' = (sign·A − r1)/τ1)."""
    r1 = np.zeros(u.size)
    decay = np.exp(-np.diff(u) / tau1)
    for i in range(u.size - 1):
        target = sign * current[i]
        r1[i + 1] = target + (r1[i] - target) * decay[i]
    return r1


def _own_charge(u: np.ndarray, current: np.ndarray, k: float, tau2: float) -> tuple[np.ndarray, np.ndarray]:
    """ca and r2 the pulse's own anodic charge builds from 0 (ca exact, r2 exact for ca linear
    over each tiny step)."""
    ca = np.zeros(u.size)
    r2 = np.zeros(u.size)
    for i in range(u.size - 1):
        h = u[i + 1] - u[i]
        j = max(current[i], 0.0)
        a = math.exp(-k * h)
        ca[i + 1] = ca[i] * a + j * (h if k == 0 else (1 - a) / k)
        e = math.exp(-h / tau2)
        slope_term = 1.0 - tau2 / h * (1.0 - e)
        r2[i + 1] = r2[i] * e + ca[i] * (1 - e) + (ca[i + 1] - ca[i]) * slope_term
    return ca, r2


def _cumtrapz(y: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Cumulative trapezoid along the last axis, 0 at the first point."""
    out = np.zeros_like(y)
    np.cumsum(0.5 * (y[..., 1:] + y[..., :-1]) * np.diff(u), axis=-1, out=out[..., 1:])
    return out


def _states(r3: np.ndarray, u: np.ndarray, tau3: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x1, x2, x3 (…, U) of three cascaded τ3 integrators fed r3 (…, U) from 0 (moments)."""
    w = np.exp(u / tau3)
    i0 = _cumtrapz(r3 * w, u)
    i1 = _cumtrapz(r3 * (w * u), u)
    i2 = _cumtrapz(r3 * (w * u * u), u)
    e = np.exp(-u / tau3)
    x1 = e / tau3 * i0
    x2 = e / tau3 ** 2 * (u * i0 - i1)
    x3 = e / (2 * tau3 ** 3) * (u * u * i0 - 2 * u * i1 + i2)
    return x1, x2, x3


def build_bursts(model: Horsager2009 | Nanduri2012, pulse: BiphasicPulse, recovery_ms: float = math.inf,
                 chunk: int = 64) -> BurstTables:
    """Tables of one pulse's effect for ``model`` (its time constants, ε and β; Nanduri's gain is
    applied by the caller) — about 1 s to build."""
    horsager = isinstance(model, Horsager2009)
    beta = model.beta if horsager else 1.0
    sign = -1.0 if horsager else 1.0            # Horsager's r1 follows −A, Nanduri's +A
    eps = model.eps / 1000.0
    k = 0.0 if math.isinf(recovery_ms) else 1.0 / recovery_ms
    if k * model.tau2 == 1.0:
        raise ValueError(f"recovery_ms must differ from tau2 ({model.tau2} ms)")
    # r3 ends with the pulse when r1 is then ≤ 0 (Horsager, cathodic first: the anodic phase drives
    # it below 0 and r2 ≥ 0), else r1's decay is followed for WINDOW_TAU1 τ1
    u, current = fine_grid(pulse, pulse.duration_ms + 1e-9)
    ends_with_pulse = _r1(u, current, model.tau1, sign)[-1] <= 0
    window = pulse.duration_ms if ends_with_pulse else pulse.duration_ms + WINDOW_TAU1 * model.tau1
    u, current = fine_grid(pulse, window)
    r1 = _r1(u, current, model.tau1, sign)
    ca_q, q = _own_charge(u, current, k, model.tau2)
    decays = np.array([charge_decay(k, model.tau2, t) for t in u])
    v, h = decays[:, 1] + decays[:, 2], decays[:, 2]         # r2(s) = r2₀·v(s) + d·h(s) + q(s)
    r1_top = float(r1.max())
    if r1_top <= 0:
        raise ValueError(f"the {model.name} model gives no response to {pulse}")
    r2_grid = np.linspace(0.0, 1.02 * r1_top / eps, GRID_R2)
    s_idx = np.searchsorted(u, np.linspace(0.0, window, GRID_S), side="left").clip(0, u.size - 1)
    full = np.empty((GRID_R2, 3))
    full_d = np.empty((GRID_R2, 3))
    partial = np.empty((GRID_S, GRID_R2))
    partial_d = np.empty((GRID_S, GRID_R2))
    peak = np.empty(GRID_R2)
    peak_d = np.empty(GRID_R2)
    for start in range(0, GRID_R2, chunk):
        r2_0 = r2_grid[start:start + chunk, None]
        arg = r1[None, :] - eps * (r2_0 * v[None, :] + q[None, :])
        pos = np.maximum(arg, 0.0)
        r3 = pos ** beta
        # d r3 / d d = β·pos^(β−1)·(−ε·h(s))
        dr3 = (beta * pos ** (beta - 1.0) if beta != 1.0 else (arg > 0).astype(float)) * (-eps * h[None, :])
        xs = _states(r3, u, model.tau3)
        xd = _states(dr3, u, model.tau3)
        sl = slice(start, start + r2_0.shape[0])
        full[sl] = np.stack([x[:, -1] for x in xs], axis=1)
        full_d[sl] = np.stack([x[:, -1] for x in xd], axis=1)
        partial[:, sl] = xs[2][:, s_idx].T
        partial_d[:, sl] = xd[2][:, s_idx].T
        top = np.argmax(arg, axis=1)
        peak[sl] = pos[np.arange(top.size), top]
        peak_d[sl] = np.where(peak[sl] > 0, -eps * h[top], 0.0)
    return BurstTables(window, float(r2_grid[1] - r2_grid[0]), full, full_d, u[s_idx], partial, partial_d,
                       peak, peak_d, float(ca_q[-1]), float(q[-1]))
