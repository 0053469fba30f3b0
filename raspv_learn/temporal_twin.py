"""The temporal model of the live node as a differentiable recurrence over a sequence.

The live model (:class:`raspv_spv.temporal_lut.TemporalState`) keeps per phosphene a 10-bit
pulse history h (bit k: a pulse k frames ago; a phosphene pulses when its requested amplitude
is above 0) and the amplitude of its latest pulse; the displayed brightness is
``table[h] · amplitude``. Indexing a table by bits has no gradient, so the twin treats each
bit as a probability p ∈ [0, 1] and takes the table's **multilinear extension**

    g(p_0 … p_9) = Σ_h table[h] · Π_k (p_k if bit k of h else 1 − p_k),

computed by contracting the table (2×…×2) one frame at a time. It equals ``table[h]`` when
every p is 0 or 1. A frame's pulse probability is p = clamp(a·(N_L − 1), 0, 1) for the
requested amplitude a: 1 for any level ≥ 1 and 0 for level 0 — exactly the live rule on the
levels the node can show — with a gradient below level 1. The latest pulse's amplitude
follows m_t = p·a + (1 − p)·m_{t−1} (the live "keep it unless a new pulse comes"). One display
frame per step (the live node advances several when display frames were dropped).
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from raspv_spv.temporal_lut import HISTORY_FRAMES, TABLE_SIZE, load_table


class TemporalTwin(nn.Module):
    """``forward(amplitude)`` with ``amplitude`` (B, T, N) in [0, 1] (level/(N_L−1) per frame)
    → (brightness (B, T, N), pulse amplitude (B, T, N), state). ``state`` (pulse probabilities
    of the last 9 frames (B, 9, N), newest first, and the latest pulse's amplitude (B, N))
    continues a sequence; None starts from no pulses, as the live node does."""

    def __init__(self, table: np.ndarray, num_levels: int, dtype: torch.dtype = torch.float32) -> None:
        super().__init__()
        table = np.asarray(table, dtype=np.float64)
        if table.shape != (TABLE_SIZE,):
            raise ValueError(f"temporal table must have {TABLE_SIZE} entries, got {table.shape}")
        self.register_buffer("table", torch.from_numpy(table).to(dtype))
        self.num_levels = int(num_levels)

    @classmethod
    def from_config(cls, config, dtype: torch.dtype = torch.float32) -> "TemporalTwin":
        """The twin of the temporal model of an :class:`~raspv_spv.config.SpvConfig`."""
        return cls(load_table(config.lut_config()), config.device.num_levels, dtype)

    def gain(self, bits: torch.Tensor) -> torch.Tensor:
        """Multilinear extension of the table at ``bits`` (..., 10): bit 0 the current frame."""
        values = self.table.reshape(1, TABLE_SIZE).expand(bits[..., 0].numel(), TABLE_SIZE)
        flat = bits.reshape(-1, HISTORY_FRAMES)
        for k in range(HISTORY_FRAMES):                 # the lowest bit is the table's fastest axis
            pairs = values.reshape(values.shape[0], -1, 2)
            p = flat[:, k:k + 1]
            values = pairs[:, :, 0] * (1.0 - p) + pairs[:, :, 1] * p
        return values.reshape(bits.shape[:-1])

    def pulse_probability(self, amplitude: torch.Tensor) -> torch.Tensor:
        return (amplitude * (self.num_levels - 1)).clamp(0.0, 1.0)

    def forward(self, amplitude: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor] | None = None):
        if amplitude.dim() != 3:
            raise ValueError(f"expected amplitudes of shape (batch, frames, phosphenes), got {tuple(amplitude.shape)}")
        batch, frames, count = amplitude.shape
        amplitude = amplitude.to(self.table.dtype)
        if state is None:
            past = amplitude.new_zeros(batch, HISTORY_FRAMES - 1, count)
            latest = amplitude.new_zeros(batch, count)
        else:
            past, latest = state
        brightness, pulses = [], []
        for t in range(frames):
            a = amplitude[:, t]
            p = self.pulse_probability(a)
            bits = torch.cat([p.unsqueeze(1), past], dim=1)          # (B, 10, N), newest first
            latest = p * a + (1.0 - p) * latest
            brightness.append(self.gain(bits.transpose(1, 2)) * latest)
            pulses.append(latest)
            past = bits[:, :-1]
        return torch.stack(brightness, 1), torch.stack(pulses, 1), (past, latest)
