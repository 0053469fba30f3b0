"""The differentiable twin of the live phosphene renderer: stimulation (batch, N) → images.

Built from the very configuration the ``spv`` node runs (:class:`~raspv_spv.config.SpvConfig`,
or the node's parameter values): the twin builds a live
:class:`~raspv_spv.simulator.PhospheneSimulator` and takes its renderer's precomputed sparse
matrices — the same phosphene map, sampling, sprite bank (Gaussian, scoreboard, axon map,
biphasic axon map, dynaphos), levels, position noise and dropout — so there is nothing to keep
in step by hand. The live renderer computes, per frame (:mod:`raspv_spv.renderer`)::

    image = clip(upsample_S(M_coarse @ w) + M_fine @ w, 0, 255)        (uint8 after rounding)

with ``w`` the brightness per phosphene, or, for levelled sprite models (one sprite per level:
biphasic axon map, dynaphos), the gain of each phosphene in the column of its pulse's level,
and ``upsample_S`` OpenCV's bilinear resize by the integer factor S (half-pixel centres,
border replicated) cropped to the image. The twin computes the same in torch: a sparse CSR
product with a custom backward (Mᵀ·grad, also CSR), ``F.interpolate(bilinear,
align_corners=False)`` (OpenCV's convention for upsampling) and a clamp, divided by 255 so
images are in [0, 1]. It stops before the rounding to uint8, which is not differentiable.

Levelled sprite models take the level as a continuous value: at amplitude a ∈ [0, 1] the
sprite is the linear blend of the sprites of the two levels around a·(N_L − 1) (level 0 is no
sprite), which is exactly the live sprite at every level the live node can show and a
gradient in between. Everything is batched: (B, N) in, (B, H, W) out.
"""
from __future__ import annotations

import warnings
from typing import Any, Mapping

import numpy as np
import scipy.sparse as sp
import torch
import torch.nn.functional as F
from torch import nn

from raspv_spv.config import SpvConfig, config_from_node_params
from raspv_spv.simulator import PhospheneSimulator


def csr_tensor(matrix: sp.spmatrix, dtype: torch.dtype) -> torch.Tensor:
    """A scipy sparse matrix as a torch sparse CSR tensor of ``dtype``."""
    m = sp.csr_matrix(matrix)
    m.sort_indices()
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Sparse CSR tensor support is in beta")
        return torch.sparse_csr_tensor(torch.from_numpy(m.indptr.astype(np.int64)),
                                       torch.from_numpy(m.indices.astype(np.int64)),
                                       torch.from_numpy(m.data).to(dtype), size=m.shape, check_invariants=False)


class _SparseProduct(torch.autograd.Function):
    """M @ X with M sparse (constant) and X dense; the backward is Mᵀ @ grad with a
    precomputed CSR transpose (faster than transposing a CSR tensor at every step)."""

    @staticmethod
    def forward(ctx, x: torch.Tensor, matrix: torch.Tensor, transposed: torch.Tensor) -> torch.Tensor:
        ctx.transposed = transposed
        return matrix @ x

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        return ctx.transposed @ grad.contiguous(), None, None


def sparse_product(matrix: torch.Tensor, transposed: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """(P, K) sparse · (K, B) dense → (P, B), differentiable in ``x``."""
    return _SparseProduct.apply(x, matrix, transposed)


class PhospheneTwin(nn.Module):
    """Phosphene images of a batch of stimulations, differentiably, for one configuration.

    ``forward(brightness)`` with ``brightness`` (B, N) in [0, 1] — the displayed brightness
    of each phosphene, as :meth:`PhospheneSimulator.brightness` returns it (level/(N_L−1)
    without the temporal model) — gives (B, H, W) images in [0, 1] (the live image / 255
    before rounding). Levelled sprite models also take ``pulse_amplitude`` (B, N): the
    amplitude of each phosphene's latest pulse (:class:`TemporalTwin` returns it); without it
    the brightness is the amplitude (temporal model off).
    """

    def __init__(self, simulator: PhospheneSimulator, dtype: torch.dtype = torch.float32) -> None:
        super().__init__()
        renderer = simulator.renderer
        self.config = simulator.config
        self.count = simulator.count
        self.width, self.height = renderer.width, renderer.height
        self.scale = renderer.scale
        self.levels = renderer.levels                      # sprites per phosphene (1: scaled by brightness)
        self.num_levels = simulator.num_levels
        self.coarse_shape = tuple(int(v) for v in renderer.bank.coarse_shape)
        self.dtype = dtype
        self._matrices = {}
        for name, m in (("coarse", renderer.matrix), ("fine", renderer.fine)):
            if m is not None:
                self._matrices[name] = (csr_tensor(m, dtype), csr_tensor(sp.csr_matrix(m.T), dtype))
        self.register_buffer("visible", torch.from_numpy((~simulator.map.dropped).astype(np.float32)).to(dtype))
        self.simulator = simulator

    # -- construction -----------------------------------------------------------------------
    @classmethod
    def from_config(cls, config: SpvConfig, dtype: torch.dtype = torch.float32) -> "PhospheneTwin":
        """The twin of ``config`` (temporal model and mode do not matter to the image)."""
        return cls(PhospheneSimulator(config), dtype)

    @classmethod
    def from_node_params(cls, params: Mapping[str, Any], dtype: torch.dtype = torch.float32) -> "PhospheneTwin":
        """The twin of the spv node's parameter values (``raspv param list spv``, a graph file)."""
        return cls.from_config(config_from_node_params(params), dtype)

    @property
    def levelled(self) -> bool:
        return self.levels > 1

    # -- per batch ----------------------------------------------------------------------------
    def weights(self, brightness: torch.Tensor, pulse_amplitude: torch.Tensor | None = None) -> torch.Tensor:
        """(B, N·levels) weights of the sprite columns."""
        if not self.levelled:
            return brightness
        amplitude = brightness if pulse_amplitude is None else pulse_amplitude
        top = self.num_levels - 1
        position = amplitude.clamp(0.0, 1.0) * top                    # continuous level
        low = torch.floor(position).detach().clamp(0, top)
        frac = position - low
        if pulse_amplitude is None:
            gain = torch.ones_like(brightness)
        else:
            gain = torch.where(amplitude > 0, brightness / amplitude.clamp_min(1e-12), torch.zeros_like(brightness))
        base = torch.arange(self.count, device=brightness.device) * self.levels
        low_i = low.long()
        out = torch.zeros(brightness.shape[0], self.count * self.levels, dtype=brightness.dtype,
                          device=brightness.device)
        # level l ≥ 1 is column l − 1; level 0 has no sprite
        lo_ok = low_i >= 1
        hi_ok = low_i < top
        lo_col = base + (low_i - 1).clamp(0, self.levels - 1)
        hi_col = base + low_i.clamp(0, self.levels - 1)
        out = out.scatter_add(1, lo_col, torch.where(lo_ok, gain * (1.0 - frac), torch.zeros_like(gain)))
        out = out.scatter_add(1, hi_col, torch.where(hi_ok, gain * frac, torch.zeros_like(gain)))
        return out

    def forward(self, brightness: torch.Tensor, pulse_amplitude: torch.Tensor | None = None) -> torch.Tensor:
        if brightness.dim() != 2 or brightness.shape[1] != self.count:
            raise ValueError(f"expected brightness of shape (batch, {self.count}), got {tuple(brightness.shape)}")
        w = self.weights(brightness.to(self.dtype), None if pulse_amplitude is None else pulse_amplitude.to(self.dtype))
        batch = w.shape[0]
        wt = w.t().contiguous()
        rows, cols = self.coarse_shape
        coarse = sparse_product(*self._matrices["coarse"], wt).t().reshape(batch, 1, rows, cols)
        if self.scale > 1:
            coarse = F.interpolate(coarse, size=(rows * self.scale, cols * self.scale), mode="bilinear",
                                   align_corners=False)[:, :, :self.height, :self.width]
        image = coarse[:, 0]
        if "fine" in self._matrices:
            image = image + sparse_product(*self._matrices["fine"], wt).t().reshape(batch, self.height, self.width)
        return image.clamp(max=255.0) / 255.0

    def render_levels(self, levels: np.ndarray | torch.Tensor) -> torch.Tensor:
        """(B, H, W) images of integer levels (B, N) with the temporal model off (no gradient
        needed: e.g. the hand-designed modes' frames)."""
        lv = torch.as_tensor(np.asarray(levels), dtype=self.dtype)
        return self.forward(lv / (self.num_levels - 1) * self.visible)
