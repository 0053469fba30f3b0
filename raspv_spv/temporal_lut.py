"""Discretised temporal perception model of the paper (§III-D): a 1024-entry look-up table.

Per phosphene, bit k of a 10-bit history is 1 when frame t−k delivered a biphasic pulse (the
mode's level was above 0), bit 0 being the current frame. Each frame lasts ``frame_ms``; a
pulse starts at the beginning of its frame. For every one of the 1024 histories the continuous
model (:mod:`raspv_spv.temporal`) is integrated over the 10 frames and the table stores the
brightness of the *current* frame — its mean over the frame (``sample="mean"``, what a viewer
sees while the frame is displayed) or its value at the frame's end (``sample="end"``) — divided
by the table's maximum, so entries lie in [0, 1] and entry 0 (no pulse for 10 frames) is 0.

Tables are built once (≈ 2 s) and cached on disk under ``$RASPV_CACHE_DIR`` (default
``~/.cache/raspv``) in a file named by a hash of every parameter. At run time
:class:`TemporalState` keeps one uint16 history per phosphene: a frame costs a shift, an OR and
one table look-up for all phosphenes. Levels above 1 bit are handled as pulse amplitude: the
gain of the history multiplies the level of the phosphene's latest pulse.
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from raspv_spv.temporal import BiphasicPulse, current_on_grid, pulse_train_breakpoints, temporal_model

HISTORY_FRAMES = 10
TABLE_SIZE = 1 << HISTORY_FRAMES
_FORMAT_VERSION = 1
SAMPLES = ("mean", "end")


@dataclass(frozen=True)
class TemporalLUTConfig:
    """Everything the table depends on. Times in ms, current in µA."""

    model: str = "horsager2009"
    frame_ms: float = 20.0           # display period (50 Hz in the paper)
    pulse_amplitude_ua: float = 20.0
    pulse_phase_ms: float = 0.45
    pulse_interphase_ms: float = 0.0
    sample: str = "mean"
    dt_ms: float = 1.0 / 256.0       # integration step; a power of two keeps times exact

    def __post_init__(self) -> None:
        if self.sample not in SAMPLES:
            raise ValueError(f"sample must be one of {SAMPLES}, got {self.sample!r}")
        temporal_model(self.model, self.dt_ms)            # validates the model name and step
        pulse = self.pulse
        if pulse.duration_ms >= self.frame_ms:
            raise ValueError(f"a biphasic pulse of {pulse.duration_ms} ms does not fit in a frame of {self.frame_ms} ms")
        if self.frame_ms / self.dt_ms > 200_000:
            raise ValueError(f"frame of {self.frame_ms} ms is too long for the integration step {self.dt_ms} ms")

    @property
    def pulse(self) -> BiphasicPulse:
        return BiphasicPulse(self.pulse_amplitude_ua, self.pulse_phase_ms, self.pulse_interphase_ms)

    def key(self) -> str:
        """Hash naming the cached table."""
        text = json.dumps({"version": _FORMAT_VERSION, "frames": HISTORY_FRAMES, **asdict(self)}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:20]


def simulate_histories(config: TemporalLUTConfig, histories: np.ndarray, chunk: int = 32) -> np.ndarray:
    """Continuous-model brightness (S, 10·steps_per_frame) of each 10-bit history (S,), frames
    oldest first; pulses start at frame starts. Not normalised."""
    model = temporal_model(config.model, config.dt_ms)
    steps = int(round(config.frame_ms / config.dt_ms))
    n = HISTORY_FRAMES * steps
    # One pulse per frame slot; a history switches slots on (frame k = bit 9-k, oldest first).
    onsets = np.arange(HISTORY_FRAMES) * steps * config.dt_ms
    times, values = pulse_train_breakpoints(onsets, config.pulse)
    per_pulse = values.size // HISTORY_FRAMES
    histories = np.asarray(histories, dtype=np.int64).ravel()
    out = np.empty((histories.size, n))
    for start in range(0, histories.size, chunk):
        h = histories[start:start + chunk]
        bits = (h[:, None] >> (HISTORY_FRAMES - 1 - np.arange(HISTORY_FRAMES))[None, :]) & 1
        currents = np.repeat(bits, per_pulse, axis=1) * values[None, :]
        out[start:start + chunk] = model.response(current_on_grid(times, currents, config.dt_ms, n))
    return out


def build_table(config: TemporalLUTConfig) -> np.ndarray:
    """The normalised 1024-entry table (float32, max 1, entry 0 = 0)."""
    steps = int(round(config.frame_ms / config.dt_ms))
    table = np.empty(TABLE_SIZE)
    hist = np.arange(TABLE_SIZE)
    for start in range(0, TABLE_SIZE, 32):
        last = simulate_histories(config, hist[start:start + 32])[:, -steps:]
        table[start:start + 32] = last.mean(axis=1) if config.sample == "mean" else last[:, -1]
    peak = table.max()
    if not np.isfinite(peak) or peak <= 0:
        raise ValueError(f"the {config.model} model gives no response to these pulses ({config.pulse}); "
                         "raise the amplitude or the phase duration")
    table = np.clip(table / peak, 0.0, 1.0)
    table[0] = 0.0
    return table.astype(np.float32)


def cache_dir() -> Path:
    return Path(os.environ.get("RASPV_CACHE_DIR") or Path.home() / ".cache" / "raspv") / "temporal_lut"


def cached_table_path(config: TemporalLUTConfig) -> Path:
    """Where the table of ``config`` is cached."""
    return cache_dir() / f"{config.model}-{config.key()}.npy"


def load_table(config: TemporalLUTConfig, use_cache: bool = True) -> np.ndarray:
    """The table for ``config``: read from the disk cache, or built and written there.
    An unwritable cache only costs the rebuild next time."""
    path = cached_table_path(config)
    if use_cache and path.exists():
        try:
            table = np.load(path, allow_pickle=False)
            if table.shape == (TABLE_SIZE,) and table.dtype == np.float32 and np.all(np.isfinite(table)):
                return table
        except (OSError, ValueError):
            pass                                   # corrupt cache file: rebuild it
    table = build_table(config)
    if use_cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
            with os.fdopen(fd, "wb") as f:
                np.save(f, table)
            os.replace(tmp, path)
        except OSError:
            pass
    return table


class TemporalState:
    """Pulse histories of ``count`` phosphenes (uint16 registers) and the amplitude of each
    phosphene's latest pulse.

    A phosphene pulses in a frame when its requested amplitude (level/(N_L−1)) is above 0. Its
    brightness is the table's gain for its pulse history times the amplitude of its latest
    pulse, so a phosphene that was just switched off keeps fading at the level it had (the
    trail), and a phosphene held at a level converges to that level.
    """

    def __init__(self, table: np.ndarray, count: int) -> None:
        table = np.asarray(table, dtype=np.float32)
        if table.shape != (TABLE_SIZE,):
            raise ValueError(f"temporal table must have {TABLE_SIZE} entries, got {table.shape}")
        self.table = table
        self.history = np.zeros(count, dtype=np.uint16)
        self.amplitude = np.zeros(count, dtype=np.float32)

    def reset(self) -> None:
        self.history[:] = 0
        self.amplitude[:] = 0

    def adopt(self, other: "TemporalState") -> None:
        """Continue ``other``'s histories (same number of phosphenes)."""
        if other.history.shape != self.history.shape:
            raise ValueError(f"cannot continue {other.history.size} pulse histories with {self.history.size} phosphenes")
        self.history[:] = other.history
        self.amplitude[:] = other.amplitude

    def step(self, amplitude: np.ndarray, frames: int = 1) -> np.ndarray:
        """Advance by ``frames`` display frames during which ``amplitude`` (N,) in [0, 1] was
        requested; return the perceived brightness (N,) float32 in [0, 1] of the current frame."""
        amp = np.asarray(amplitude, dtype=np.float32)
        on = amp > 0
        frames = max(1, min(int(frames), HISTORY_FRAMES))
        fill = np.uint16((1 << frames) - 1)
        h = self.history
        np.left_shift(h, np.uint16(frames), out=h)
        h |= on.astype(np.uint16) * fill
        h &= np.uint16(TABLE_SIZE - 1)
        np.copyto(self.amplitude, amp, where=on)
        return self.table[h] * self.amplitude
