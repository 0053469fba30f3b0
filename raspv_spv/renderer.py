"""Phosphene image renderer: brightness per phosphene → image in one sparse product, no ROS.

Everything that depends only on the map is precomputed: a sparse matrix M (pixels × phosphenes,
CSC, float32) whose column i holds phosphene i's sprite, sampled at every pixel centre around
its displayed (noisy) centre and scaled to 255. A frame is ``M @ brightness`` followed by a
saturating conversion to uint8 — overlapping sprites sum and saturate (paper Appendix A-A) —
so the cost per frame depends on the number of lit sprite pixels, not on the sprite's shape.
Dropped phosphenes have empty columns. Output mono8 (H, W) or green-only rgb8 (H, W, 3) for
headsets (paper §III-E).
"""
from __future__ import annotations

import math

import cv2
import numpy as np
import scipy.sparse as sp

from raspv_spv.sprites import Sprite

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
    """Precomputed sprites of one map; :meth:`render` turns brightness into an image."""

    def __init__(self, display_centres: np.ndarray, visible: np.ndarray, width: int, height: int,
                 sprite: Sprite, output_format: str = "mono8") -> None:
        if output_format not in OUTPUT_FORMATS:
            raise ValueError(f"output format must be one of {', '.join(OUTPUT_FORMATS)}, got {output_format!r}")
        self.width, self.height = int(width), int(height)
        self.count = len(display_centres)
        self.sprite = sprite
        self.output_format = output_format
        self.matrix = sprite_matrix(display_centres, visible, self.width, self.height, sprite)
        self._zeros = np.zeros((self.height, self.width), np.uint8)

    @property
    def nbytes(self) -> int:
        """Memory held by the precomputed matrix."""
        m = self.matrix
        return int(m.data.nbytes + m.indices.nbytes + m.indptr.nbytes + self._zeros.nbytes)

    def render_mono(self, brightness: np.ndarray) -> np.ndarray:
        """(H, W) uint8 image for ``brightness`` (N,) in [0, 1] (values above 1 saturate)."""
        b = np.asarray(brightness, dtype=np.float32)
        if b.shape != (self.count,):
            raise ValueError(f"expected brightness for {self.count} phosphenes, got shape {b.shape}")
        summed = self.matrix @ b
        return cv2.convertScaleAbs(summed.reshape(self.height, self.width))

    def render(self, brightness: np.ndarray) -> np.ndarray:
        """The image in this renderer's output format: mono8 (H, W) or green rgb8 (H, W, 3)."""
        mono = self.render_mono(brightness)
        if self.output_format == "green":
            return cv2.merge([self._zeros, mono, self._zeros])
        return mono
