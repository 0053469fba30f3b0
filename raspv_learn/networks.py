"""The encoder (camera → stimulation map) and the decoder (phosphene image → walker classes).

Encoder: a small U-Net on the encoder's input grid (:func:`raspv_spv.modes.learned.encoder_inputs`:
grey, nearness, depth present, scene-class fractions) — two stride-2 stages and a dilated
context layer, upsampled back with skip connections to a stimulation map s ∈ [0, 1] of the
input's size (sigmoid). Fully convolutional, so any camera resolution works; ≈ 27 k weights at
16 features. Each phosphene takes s bilinearly at its camera pixel and is quantised to a level
with :func:`quantise_levels` (straight-through gradient), as the live mode does.

Decoder (the computational observer): three stride-2-or-dilated convolution stages on the
phosphene image (B, 1, H, W) → logits of the walker classes (floor, wall, obstacle) on the
target grid (H/stride, W/stride). The same architecture reads every mode's images.
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

NUM_CLASSES = 3          # floor, wall, obstacle (walker classes 1..3; 0 is not scored)


def _conv(cin: int, cout: int, stride: int = 1, dilation: int = 1) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(cin, cout, 3, stride=stride, padding=dilation, dilation=dilation),
                         nn.ReLU(inplace=True))


class Encoder(nn.Module):
    """(B, C, h, w) → (B, 1, h, w) stimulation in [0, 1]. The 3×3 convolutions sit where the
    grid is coarse or thin; the way up mixes channels with 1×1 convolutions and smooths with
    the last 3×3 (≈ 18 M multiply-adds on a 74×55 input at 16 features: ~1 ms on one core)."""

    def __init__(self, channels: int, features: int = 16) -> None:
        super().__init__()
        f = features
        self.inp = _conv(channels, f)
        self.down1 = _conv(f, 2 * f, stride=2)
        self.down2 = _conv(2 * f, 2 * f, stride=2)
        self.context = _conv(2 * f, 2 * f, dilation=2)
        self.up1 = nn.Sequential(nn.Conv2d(4 * f, 2 * f, 1), nn.ReLU(inplace=True))
        self.up2 = nn.Sequential(nn.Conv2d(3 * f, f, 1), nn.ReLU(inplace=True))
        self.out = nn.Conv2d(f, 1, 3, padding=1)
        # start with levels spread over the whole range: a random but informative projection the
        # decoder can read at once (a narrow start quantises to one level everywhere, the images
        # carry nothing, and joint training does not leave that state)
        with torch.no_grad():
            self.out.weight.mul_(5.0)
            self.out.bias.zero_()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        a = self.inp(x)
        b = self.down1(a)
        c = self.context(self.down2(b))
        c = F.interpolate(c, size=b.shape[-2:], mode="bilinear", align_corners=False)
        b = self.up1(torch.cat([b, c], 1))
        b = F.interpolate(b, size=a.shape[-2:], mode="bilinear", align_corners=False)
        return torch.sigmoid(self.out(self.up2(torch.cat([a, b], 1))))


class Decoder(nn.Module):
    """(B, 1, H, W) phosphene images → (B, NUM_CLASSES, H/stride, W/stride) logits."""

    def __init__(self, stride: int = 4, features: int = 24) -> None:
        super().__init__()
        steps = int(round(math.log2(stride)))
        if 2 ** steps != stride:
            raise ValueError(f"the decoder's stride must be a power of two, got {stride}")
        f = features
        layers, cin = [], 1
        for i in range(steps):
            cout = f if i == steps - 1 else max(8, f // 2)
            layers.append(_conv(cin, cout, stride=2))
            cin = cout
        layers += [_conv(cin, f, dilation=2), _conv(f, f, dilation=4), _conv(f, f)]
        self.body = nn.Sequential(*layers)
        self.out = nn.Conv2d(f, NUM_CLASSES, 1)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return self.out(self.body(images))


class _RoundStraightThrough(torch.autograd.Function):
    @staticmethod
    def forward(ctx, x: torch.Tensor) -> torch.Tensor:
        return torch.floor(x + 0.5)

    @staticmethod
    def backward(ctx, grad: torch.Tensor) -> torch.Tensor:
        return grad


def quantise_levels(stimulation: torch.Tensor, num_levels: int) -> torch.Tensor:
    """Levels ⌊s·(N_L − 1) + ½⌋ as floats (the live rule,
    :func:`raspv_spv.modes.learned.stimulation_levels`), gradient passed straight through."""
    return _RoundStraightThrough.apply(stimulation.clamp(0.0, 1.0) * (num_levels - 1))


def sample_at(maps: torch.Tensor, grid: torch.Tensor) -> torch.Tensor:
    """(B, 1, h, w) maps sampled bilinearly at ``grid`` (N, 2) normalised (x, y) →  (B, N)
    (``align_corners=False``, border clamped: the live mode's :func:`sample_map`)."""
    g = grid.to(maps.dtype).reshape(1, 1, -1, 2).expand(maps.shape[0], 1, -1, 2)
    return F.grid_sample(maps, g, mode="bilinear", padding_mode="border", align_corners=False)[:, 0, 0]
