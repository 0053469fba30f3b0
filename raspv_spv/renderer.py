"""Phosphene image renderer: brightness per phosphene → image in one sparse product, no ROS.

Everything that depends only on the map is precomputed: a sparse matrix M (pixels × phosphenes,
CSC, float32) whose column i holds phosphene i's sprite, sampled at every pixel centre around
its displayed (noisy) centre and scaled to 255. A frame is ``M @ brightness`` followed by a
saturating conversion to uint8 — overlapping sprites sum and saturate (paper Appendix A-A) —
so the cost per frame depends on the number of lit sprite pixels, not on the sprite's shape.
Dropped phosphenes have empty columns. Output mono8 (H, W) or green-only rgb8 (H, W, 3) for
headsets (paper §III-E).

Sprite models (:mod:`raspv_spv.sprite_models`) hand the renderer a precomputed
:class:`~raspv_spv.sprite_models.SpriteBank`: the same product on a grid ``scale`` times
coarser than the image (smooth tissue sprites), followed by a bilinear resize, plus a product
at full resolution for the phosphenes too small for that grid; for levelled models (one sprite
per level) the products take each phosphene's column for its level.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import cv2
import numpy as np
import scipy.sparse as sp

from raspv_spv.sprites import Sprite

if TYPE_CHECKING:
    from raspv_spv.sprite_models import SpriteBank

OUTPUT_FORMATS = ("mono8", "green")


def sprite_matrix(centres: np.ndarray, visible: np.ndarray, width: int, height: int, sprite: Sprite,
                  peak: float = 255.0, chunk_entries: int = 4_000_000) -> sp.csc_matrix:
    """Sparse (height·width, N) float32 matrix of the sprites at ``centres`` (N, 2) px
    (continuous, origin at the image's top-left corner); columns of invisible phosphenes are
    empty. Built in chunks of about ``chunk_entries`` candidate pixels to bound memory."""
    centres = np.asarray(centres, dtype=np.float64)
    n = len(centres)
    reach = int(math.ceil(sprite.radius_px)) + 1
    off = np.arange(-reach, reach + 1)
    oy, ox = np.meshgrid(off, off, indexing="ij")            # row-major: sorted pixel indices
    oy, ox = oy.ravel(), ox.ravel()
    per = oy.size
    step = max(1, chunk_entries // per)
    data_parts, index_parts = [], []
    counts = np.zeros(n, dtype=np.int64)
    vis_idx = np.flatnonzero(np.asarray(visible, dtype=bool))
    for start in range(0, vis_idx.size, step):
        ids = vis_idx[start:start + step]
        base = np.floor(centres[ids]).astype(np.int64)       # pixel containing the centre
        px = base[:, 0:1] + ox[None, :]
        py = base[:, 1:2] + oy[None, :]
        w = sprite.weights(px + 0.5 - centres[ids, 0:1], py + 0.5 - centres[ids, 1:2])
        keep = (w > 0) & (px >= 0) & (px < width) & (py >= 0) & (py < height)
        counts[ids] = keep.sum(axis=1)
        data_parts.append((w[keep] * peak).astype(np.float32))
        index_parts.append((py[keep] * width + px[keep]).astype(np.int32))
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    data = np.concatenate(data_parts) if data_parts else np.zeros(0, np.float32)
    indices = np.concatenate(index_parts) if index_parts else np.zeros(0, np.int32)
    index_dtype = np.int32 if indptr[-1] < 2**31 else np.int64
    return sp.csc_matrix((data, indices.astype(index_dtype, copy=False), indptr.astype(index_dtype)),
                         shape=(height * width, n))


class Renderer:
    """Precomputed sprites of one map; :meth:`render` turns brightness into an image.

    Built from sprite positions and a :class:`~raspv_spv.sprites.Sprite` (the paper's model),
    or from a sprite model's bank with :meth:`from_bank`.
    """

    def __init__(self, display_centres: np.ndarray, visible: np.ndarray, width: int, height: int,
                 sprite: Sprite, output_format: str = "mono8") -> None:
        from raspv_spv.sprite_models import SpriteBank

        matrix = sprite_matrix(display_centres, visible, int(width), int(height), sprite)
        self._setup(SpriteBank(matrix, int(width), int(height)), output_format)
        self.sprite = sprite

    @classmethod
    def from_bank(cls, bank: "SpriteBank", visible: np.ndarray, output_format: str = "mono8") -> "Renderer":
        """A renderer of ``bank``'s sprites; phosphenes with ``visible`` False are never drawn."""
        r = cls.__new__(cls)
        visible = np.asarray(visible, dtype=bool)
        if not visible.all():
            keep = sp.diags(np.repeat(visible, bank.levels).astype(np.float32), format="csc")
            parts = [None if m is None else sp.csc_matrix(m @ keep) for m in (bank.matrix, bank.fine)]
            for m in parts:
                if m is not None:
                    m.eliminate_zeros()
            bank = type(bank)(parts[0], bank.width, bank.height, bank.scale, bank.levels, bank.build_s, bank.cached,
                              bank.gain, parts[1])
        r._setup(bank, output_format)
        r.sprite = None
        return r

    def _setup(self, bank: "SpriteBank", output_format: str) -> None:
        if output_format not in OUTPUT_FORMATS:
            raise ValueError(f"output format must be one of {', '.join(OUTPUT_FORMATS)}, got {output_format!r}")
        self.bank = bank
        self.width, self.height = bank.width, bank.height
        self.scale, self.levels = bank.scale, bank.levels
        self.count = bank.matrix.shape[1] // bank.levels
        self.output_format = output_format
        self.matrix = bank.matrix
        self.fine = bank.fine
        self._coarse = bank.coarse_shape
        self._zeros = np.zeros((self.height, self.width), np.uint8)

    @property
    def nbytes(self) -> int:
        """Memory held by the precomputed matrices."""
        return int(self.bank.nbytes + self._zeros.nbytes)

    def render_mono(self, brightness: np.ndarray, levels: np.ndarray | None = None) -> np.ndarray:
        """(H, W) uint8 image for ``brightness`` (N,) in [0, 1] (values above 1 saturate).
        Levelled banks also need each phosphene's sprite level ``levels`` (N,) in 1 … L (0:
        nothing drawn); its brightness then scales that level's sprite."""
        return cv2.convertScaleAbs(self.render_float(brightness, levels))

    def render_float(self, brightness: np.ndarray, levels: np.ndarray | None = None) -> np.ndarray:
        """(H, W) float32 image before the saturating conversion to uint8 (grey levels, ≥ 0,
        unclipped): what :meth:`render_mono` rounds; the differentiable twin is checked on it."""
        b = np.asarray(brightness, dtype=np.float32)
        if b.shape != (self.count,):
            raise ValueError(f"expected brightness for {self.count} phosphenes, got shape {b.shape}")
        if self.levels == 1:
            summed = self.matrix @ b
            fine = self.fine @ b if self.fine is not None else None
        else:
            if levels is None:
                raise ValueError("this renderer draws one sprite per level: pass the phosphenes' levels")
            lv = np.asarray(levels)
            on = np.flatnonzero((lv > 0) & (b > 0))
            cols = on * self.levels + np.minimum(lv[on].astype(np.int64), self.levels) - 1
            summed = self.matrix[:, cols] @ b[on] if on.size else np.zeros(self.matrix.shape[0], np.float32)
            fine = None
            if self.fine is not None:
                fine = self.fine[:, cols] @ b[on] if on.size else np.zeros(self.fine.shape[0], np.float32)
        image = summed.reshape(self._coarse)
        if self.scale > 1:
            rows, cols = self._coarse
            image = cv2.resize(image, (cols * self.scale, rows * self.scale), interpolation=cv2.INTER_LINEAR)
            image = image[:self.height, :self.width]
        if fine is not None:
            image = image + fine.reshape(self.height, self.width)
        return image

    def render(self, brightness: np.ndarray, levels: np.ndarray | None = None) -> np.ndarray:
        """The image in this renderer's output format: mono8 (H, W) or green rgb8 (H, W, 3)."""
        mono = self.render_mono(brightness, levels)
        if self.output_format == "green":
            return cv2.merge([self._zeros, mono, self._zeros])
        return mono
