"""The temporal model at any frame time: Horsager 2009 / Nanduri 2012 advanced exactly by the
real time between display frames, per phosphene, vectorised (no ROS).

The implant stimulates on its own clock: every 1/``pulse_rate_hz`` s each phosphene whose
requested level is above 0 gets one biphasic pulse (cathodic first, the device's amplitude and
phase). The display samples the perceived brightness whenever it draws a frame — at 50, 72, 90,
120 Hz or at the irregular times of a display that follows its input — so the display rate no
longer sets the stimulation rate, and no frame waits for a tick of the model.

Exact update. Between pulses every stage is linear and advances by closed-form exponentials:
three τ3 integrators x ← E(Δt)·x (E = e^{−a}·[[1,0,0],[a,1,0],[a²/2,a,1]], a = Δt/τ3), charge
ca ← e^{−kΔt}·ca (k = 1/``recovery_ms``, 0 in pulse2percept's model) and r2 following it.
A pulse adds, over a window after its onset (0.9 ms for Horsager's model, 9.3 ms for Nanduri's),
the state read from
:mod:`raspv_spv.temporal_bursts` for the r2 it meets (linear interpolation on a 1024-point grid
plus the first-order term in ca − r2); a frame inside that window reads the partial burst. The
result equals the continuous model (forward Euler as its step → 0) to ~1.2e-5 of the peak at
any sample time (tests/spv/test_temporal_recursive.py checks 1e-4 at 50 Hz, 90 Hz, jittered
frame times and every 1/4 ms). State and tables are float32; per frame: one 3-vector product per
phosphene, plus ~15 NumPy operations when a pulse falls in the interval.

Brightness. As with the look-up table, the level of a phosphene's latest pulse is its amplitude
and the model's response how much of it is perceived now: brightness = amplitude ·
y(t)/y_ref, clipped to [0, 1], with y_ref the largest response to pulses at the pulse rate
(computed once with the model itself). Nanduri's gain uses the largest r3 so far (pulse2percept
uses the largest of the whole simulated trace: the same for pulses of one amplitude, whose
first burst is the largest).

Charge recovery. pulse2percept's ca never recovers, so a phosphene held on fades to nothing
within ~15 s and stays dead; the look-up table bounds this with its 10-frame window. The headset
path leaks ca back with ``recovery_ms`` = 200 ms (10 frames at 50 Hz: the same steady-state
charge as the window); ``math.inf`` is pulse2percept's model.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from raspv_spv.temporal import BiphasicPulse, Nanduri2012, temporal_model
from raspv_spv.temporal_bursts import BurstTables, build_bursts, charge_decay

MAX_PULSES_PER_STEP = 3000      # a longer gap (a stall, a paused replay) restarts from rest
REFERENCE_S = 2.0               # y_ref: the largest response over this much continuous pulsing
DEFAULT_RECOVERY_MS = 200.0
DTYPE = np.float32              # state and tables: float32 rounding (6e-8) is far below the 1e-4 asked


@dataclass(frozen=True)
class RecursiveConfig:
    """Model, stimulation and charge recovery. Times in ms (rate in Hz), current in µA."""

    model: str = "horsager2009"
    pulse_rate_hz: float = 50.0
    pulse_amplitude_ua: float = 20.0
    pulse_phase_ms: float = 0.45
    pulse_interphase_ms: float = 0.0
    recovery_ms: float = DEFAULT_RECOVERY_MS

    def __post_init__(self) -> None:
        m = temporal_model(self.model)
        if not (math.isfinite(self.pulse_rate_hz) and self.pulse_rate_hz > 0):
            raise ValueError(f"pulse rate must be a positive number of Hz, got {self.pulse_rate_hz}")
        if not self.recovery_ms > 0:
            raise ValueError(f"charge recovery time must be > 0 ms (inf: never), got {self.recovery_ms}")
        window = self.pulse.duration_ms + 20.0 * m.tau1
        if 1000.0 / self.pulse_rate_hz < window:
            raise ValueError(f"pulses at {self.pulse_rate_hz:g} Hz are closer than one pulse's response window "
                             f"({window:.1f} ms): at most {1000.0 / window:.0f} Hz")

    @property
    def pulse(self) -> BiphasicPulse:
        return BiphasicPulse(self.pulse_amplitude_ua, self.pulse_phase_ms, self.pulse_interphase_ms)

    @property
    def period_ms(self) -> float:
        return 1000.0 / self.pulse_rate_hz


def _transition(dt: float, tau3: float, tau2: float, k: float) -> np.ndarray:
    """(5, 5) free evolution over ``dt`` ms of a state row (x1, x2, x3, r2, ca): three τ3
    integrators, r2 following ca, ca leaking at rate ``k`` (row vectors: state @ M)."""
    a = dt / tau3
    e = math.exp(-a)
    m = np.zeros((5, 5))
    m[:3, :3] = e * np.array([[1.0, a, a * a / 2], [0.0, 1.0, a], [0.0, 0.0, 1.0]])
    ca_a, r2_b, r2_c = charge_decay(k, tau2, dt)
    m[3, 3] = r2_b
    m[4, 3] = r2_c
    m[4, 4] = ca_a
    return m


def _output_row(dt: float, tau3: float, scale: float = 1.0) -> np.ndarray:
    """x3 after ``dt`` ms of free decay, times ``scale``, as float32 weights of (x1, x2, x3)."""
    a = dt / tau3
    e = math.exp(-a) * scale
    return np.array([e * a * a / 2, e * a, e], DTYPE)


@functools.lru_cache(maxsize=8)
def recursive_model(config: RecursiveConfig) -> "RecursiveModel":
    """The model of ``config`` (tables built once per process, ~1 s)."""
    return RecursiveModel(config)


class RecursiveModel:
    """Constants and tables of one configuration, shared by every :class:`RecursiveTemporalState`."""

    def __init__(self, config: RecursiveConfig) -> None:
        self.config = config
        self.params = temporal_model(config.model)
        self.nanduri = isinstance(self.params, Nanduri2012)
        self.k = 0.0 if math.isinf(config.recovery_ms) else 1.0 / config.recovery_ms
        self.bursts: BurstTables = build_bursts(self.params, config.pulse, config.recovery_ms)
        b = self.bursts
        self.window = b.window_ms
        # (9, G + 1): per r2 grid point, the state a pulse adds (x1, x2, x3), the step to the next
        # grid point (3 rows: one take and one multiply-add interpolate) and the derivative in d
        # (3 rows; not interpolated: the d term is ~1e-4 of the burst, its interpolation 1e-3 of
        # that); column G is 0: past the grid, and where no pulse is delivered
        # (11, G + 2): per r2 grid point, the state a pulse adds (x1, x2, x3), the pulse's own
        # charge (r2, ca; not scaled by Nanduri's gain), the step to the next grid point (3 rows:
        # one take and one multiply-add interpolate) and the derivative in d (3 rows; not
        # interpolated: the d term is ~1e-4 of the burst, its interpolation 1e-3 of that); columns
        # G and G + 1 are 0: past the grid, and where no pulse is delivered. One take of the rows
        # (axis 1) per pulse, every later operation on contiguous (3, N) rows
        g = b.full.shape[0]
        table = np.zeros((11, g + 2))
        table[:3, :g] = b.full.T
        table[3, :g], table[4, :g] = b.r2_after, b.ca_after
        table[5:8, :g - 1] = np.diff(b.full.T, axis=1)
        table[8:, :g] = b.full_d.T
        self.table = np.ascontiguousarray(table, dtype=DTYPE)
        self.no_pulse = g
        self.inv_step = DTYPE(1.0 / b.r2_step)
        self.last_index = DTYPE(b.full.shape[0] - 1)
        # partial bursts (S, G + 2, 2): x3 and its d-derivative inside the window
        self.partial = np.concatenate([np.stack([b.partial, b.partial_d], axis=2), np.zeros((b.s_grid.size, 2, 2))],
                                      axis=1)
        self.through_window = _transition(b.window_ms, self.params.tau3, self.params.tau2, self.k)
        self._intervals: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self.y_ref = 1.0
        self.y_ref = self._reference()

    def interval(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """For a pulse ``dt`` ms after the reference time (column states, float32): (7, 5) the
        free evolution to the pulse and through its window (5 rows; the burst is added apart),
        then r2 and ca at the pulse (2 rows); (3, 5) x1, x2, x3 at the pulse. Cached: the pulse
        clock is regular, so every pulse after the first meets the same interval."""
        key = round(dt, 9)
        found = self._intervals.get(key)
        if found is None:
            if len(self._intervals) > 64:
                self._intervals.clear()
            m = _transition(dt, self.params.tau3, self.params.tau2, self.k).T
            found = self._intervals[key] = (np.ascontiguousarray(np.vstack([self.through_window.T @ m, m[3:]]), DTYPE),
                                            np.ascontiguousarray(m[:3], dtype=DTYPE))
        return found

    def gain(self, peak: np.ndarray) -> np.ndarray:
        """Nanduri's r3 scale for the largest r3 so far (0 where nothing fired)."""
        p = self.params
        with np.errstate(divide="ignore", invalid="ignore"):
            g = p.asymptote / peak / (1.0 + np.exp(-(peak - p.shift) / p.slope))
        return np.where(peak > 0, g, 0.0)

    def _reference(self) -> float:
        state = RecursiveTemporalState(self, 1, normalise=False)
        on = np.ones(1)
        state.advance(0.0, on)
        times = np.arange(1, int(REFERENCE_S * 2000)) * 0.5
        return float(max(state.advance(t, on)[0] for t in times))


class RecursiveTemporalState:
    """Temporal state of ``count`` phosphenes under one :class:`RecursiveModel`.

    :meth:`advance` (time in ms, any increasing sequence) is the display's call; :meth:`step`
    advances by whole frames of ``frame_ms`` (offline sequences, the look-up table's interface).
    ``amplitude`` (N,) is the level of each phosphene's latest pulse, in [0, 1].
    """

    def __init__(self, model: RecursiveModel, count: int, frame_ms: float = 20.0, normalise: bool = True) -> None:
        self.model = model
        self.count = int(count)
        self.frame_ms = float(frame_ms)
        self.normalise = normalise
        self._norm = (model.params.scale_out if model.nanduri else 1.0) / (model.y_ref if normalise else 1.0)
        self.reset()

    def reset(self) -> None:
        n = self.count
        # rows x1, x2, x3, r2, ca at t_ref, every burst begun so far included; the state before
        # the latest pulse (the other buffer, ``_before_dt`` ms before it) is read only by a frame
        # inside that pulse's window
        self._buffers = (np.zeros((7, n), DTYPE), np.zeros((7, n), DTYPE))   # state rows, then r2, ca at the next pulse
        self._current = 0
        self.state = self._buffers[0][:5]
        self._before = self._buffers[1][:5]
        self._before_dt = 0.0
        self.top = np.zeros(n)               # Nanduri: the largest r3 so far
        self.pulse_index = np.full(n, self.model.no_pulse, np.intp)   # the latest pulse's r2 grid index (G: none)
        self.pulse_weight = np.zeros(n, DTYPE)
        self.pulse_d = np.zeros(n, DTYPE)
        self.pulse_scale: np.ndarray | None = None      # Nanduri: its burst's scale
        self._pulsed = False                 # the latest pulse reached a phosphene
        self.amplitude = np.zeros(n, np.float32)
        self.request = np.zeros(n, np.float32)
        self._on_mask = np.zeros(n, bool)
        self._off_mask = np.ones(n, bool)
        self._index = np.zeros(n, DTYPE)
        self._whole = np.zeros(n, DTYPE)
        self._term = np.zeros((3, n), DTYPE)
        self.t_ref = 0.0                     # ms
        self.t_pulse = -math.inf             # onset of the latest pulse [ms]
        self.next_pulse = 0.0
        self.t_last: float | None = None

    def adopt(self, other: "RecursiveTemporalState") -> None:
        """Continue ``other``'s state (same number of phosphenes, same model)."""
        if other.count != self.count or other.model is not self.model:
            raise ValueError("cannot continue a temporal state of another model or number of phosphenes")
        for name in ("top", "pulse_index", "pulse_weight", "pulse_d", "amplitude", "request",
                     "_on_mask", "_off_mask"):
            np.copyto(getattr(self, name), getattr(other, name))
        np.copyto(self._buffers[0], other._buffers[other._current])
        np.copyto(self._buffers[1], other._buffers[1 - other._current])
        self._current, self.state, self._before = 0, self._buffers[0][:5], self._buffers[1][:5]
        self.pulse_scale = None if other.pulse_scale is None else other.pulse_scale.copy()
        self._before_dt, self._pulsed = other._before_dt, other._pulsed
        self.t_ref, self.t_pulse, self.next_pulse, self.t_last = other.t_ref, other.t_pulse, other.next_pulse, other.t_last

    # -- the update -------------------------------------------------------------------------------
    def _pulse(self, t_p: float) -> None:
        """Deliver the stimulation clock's pulse at ``t_p`` [ms] with the current request
        (the masks set by :meth:`advance`). In place on preallocated float32 rows: about fifteen
        NumPy operations for all phosphenes."""
        m = self.model
        dt = t_p - self.t_ref if t_p > self.t_ref else 0.0
        evolve = m.interval(dt)[0]
        # one product: the state through the window (the burst added below), and r2, ca at the pulse;
        # the state before the pulse stays in the other buffer, for a frame inside the window
        out = self._buffers[1 - self._current]
        np.matmul(evolve, self.state, out=out)
        r2, ca = out[5], out[6]
        d = np.subtract(ca, r2, out=self.pulse_d)                      # ca − r2 at the pulse
        f = np.multiply(r2, m.inv_step, out=self._index)
        np.minimum(f, m.last_index, out=f)
        whole = np.floor(f, out=self._whole)
        w = np.subtract(f, whole, out=self.pulse_weight)               # interpolation weight
        i0 = self.pulse_index
        np.copyto(i0, whole, casting="unsafe")
        np.putmask(i0, self._off_mask, m.no_pulse)                     # column G: nothing added
        rows = m.table.take(i0, axis=1)                                 # (11, N)
        burst = rows[:3]
        burst += np.multiply(w, rows[5:8], out=self._term)
        burst += np.multiply(d, rows[8:], out=self._term)              # x1, x2, x3 the pulse adds
        if m.nanduri:
            t = m.bursts
            grid = np.arange(t.peak.size) * t.r2_step
            peak = np.maximum(np.interp(r2, grid, t.peak, right=0.0) + d * np.interp(r2, grid, t.peak_d, right=0.0), 0.0)
            self.top = np.where(self._on_mask, np.maximum(self.top, peak), self.top)
            self.pulse_scale = self._on_mask * m.gain(self.top)
            burst *= self.pulse_scale.astype(DTYPE)
        new = out[:5]
        new += rows[:5]                                                 # the burst and its own charge (r2, ca)
        self._before, self.state, self._before_dt = self.state, new, dt
        self._current = 1 - self._current
        np.putmask(self.amplitude, self._on_mask, self.request)
        self.t_pulse, self.t_ref = t_p, t_p + m.window

    def _response(self, t: float, scale: float = 1.0) -> np.ndarray:
        """The model's output y (N,) at ``t`` ≥ the latest pulse [ms], times ``scale``."""
        m = self.model
        tau3 = m.params.tau3
        s = t - self.t_pulse
        if s >= m.window:
            return _output_row(t - self.t_ref, tau3, scale) @ self.state[:3]
        # inside the latest pulse's window: the state at the pulse decaying, plus the partial burst
        to_x = m.interval(self._before_dt)[1]
        y = (_output_row(s, tau3, scale) @ to_x) @ self._before
        if not self._pulsed:
            return y
        grid = m.bursts.s_grid
        j = min(int(s / grid[-1] * (grid.size - 1)), grid.size - 2)
        ws = (s - grid[j]) / (grid[j + 1] - grid[j])
        i0, w = self.pulse_index, self.pulse_weight[:, None]
        rows = m.partial[j] * (1 - ws) + m.partial[j + 1] * ws           # (G + 2, 2) at s
        at = rows.take(i0, axis=0) * (1 - w) + rows.take(i0 + 1, axis=0) * w
        part = (at[:, 0] + self.pulse_d * at[:, 1]) * scale
        if self.pulse_scale is not None:
            part *= self.pulse_scale
        return np.maximum(y + part, 0.0).astype(DTYPE)

    def advance(self, t_ms: float, amplitude: np.ndarray) -> np.ndarray:
        """Advance to ``t_ms`` delivering the pulses due since the last call (with the amplitudes
        requested then), return the brightness (N,) float32 at ``t_ms`` (``normalise=False``: the
        model's output y), and request
        ``amplitude`` (N,) in [0, 1] from now on. Time going back restarts from rest."""
        t = float(t_ms)
        if self.t_last is not None and t < self.t_last:
            self.reset()
        if self.t_last is None:
            self.t_last = self.t_ref = self.next_pulse = t
        period = self.model.config.period_ms
        # pulses at next_pulse + i·period < t (one exactly at t takes the request made now)
        due = max(0, int(math.ceil((t - self.next_pulse) / period - 1e-9)))
        if due > MAX_PULSES_PER_STEP:                 # a long gap: what came before has faded
            request, next_pulse = self.request.copy(), self.next_pulse
            self.reset()
            self.next_pulse, self.t_last = next_pulse, t
            self.request[:] = request
            self.next_pulse += (due - MAX_PULSES_PER_STEP) * period
            self.t_ref = self.next_pulse
            due = MAX_PULSES_PER_STEP
        if due:                                       # (once per request, for all its pulses)
            np.greater(self.request, 0, out=self._on_mask)
            np.logical_not(self._on_mask, out=self._off_mask)
            self._pulsed = bool(self._on_mask.any())
        for _ in range(due):
            self._pulse(self.next_pulse)
            self.next_pulse += period
        y = self._response(t, self._norm)
        if self.normalise:                            # y ≥ 0: every stage is fed non-negative r3
            brightness = np.minimum(y, 1.0, out=y)
            brightness *= self.amplitude
        else:
            brightness = y
        np.copyto(self.request, amplitude)
        self.t_last = t
        return brightness

    def step(self, amplitude: np.ndarray, frames: int = 1) -> np.ndarray:
        """Advance by ``frames`` frames of ``frame_ms`` (see :meth:`advance`)."""
        t = 0.0 if self.t_last is None else self.t_last + max(1, int(frames)) * self.frame_ms
        return self.advance(t, amplitude)
