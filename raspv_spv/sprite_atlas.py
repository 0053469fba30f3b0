"""A renderer's sprites as one texture atlas (no ROS): every sprite a patch, drawn by weight.

A phosphene image is ``saturate(upsample(C @ w) + F @ w)`` (:class:`raspv_spv.renderer.Renderer`):
each phosphene's sprite is a fixed patch of pixels scaled by its weight. :class:`SpriteAtlas`
holds each sprite's bounding box on its grid (coarse or fine) and packs the patches into one
texture (shelf packing, tallest first), so a client — the browser's WebGL drawing of the
headset bridge's levels stream (:mod:`raspv_hmd.levels_stream`) — can draw any frame from one
weight per phosphene. :meth:`SpriteAtlas.render` is the reference of that drawing (equal to the
renderer's image within one grey level once the atlas is rounded to half floats). The spv node
builds the atlas with its simulator (:meth:`raspv_spv.simulator.PhospheneSimulator.sprite_atlas`)
and publishes it latched (``/spv/sprites``, :mod:`raspv_spv.sprites_msg`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sp

MAX_ATLAS_SIDE = 4096           # texels; WebGL 2 guarantees at least 2048, every browser here offers 4096+


class AtlasTooLarge(ValueError):
    """The sprites do not fit one texture of :data:`MAX_ATLAS_SIDE`²: the client gets images instead."""


@dataclass
class SpriteAtlas:
    """Every sprite of one map as a patch of one texture. ``patches`` (P, 8) int32: column, grid
    (0 coarse, 1 fine), x, y, w, h (px on that grid), atlas x, atlas y; ``atlas`` (H, W) float32."""

    map_id: int
    width: int
    height: int
    scale: int
    levels: int
    num_levels: int
    green: bool
    patches: np.ndarray
    atlas: np.ndarray

    @property
    def coarse_shape(self) -> tuple[int, int]:
        """(rows, cols) of the coarse grid."""
        return -(-self.height // self.scale), -(-self.width // self.scale)

    @classmethod
    def from_matrices(cls, coarse: sp.csc_matrix, fine: sp.csc_matrix | None, width: int, height: int, scale: int,
                      levels: int, num_levels: int, map_id: int = 0, green: bool = False,
                      max_side: int = MAX_ATLAS_SIDE) -> "SpriteAtlas":
        """The atlas of a sprite bank's matrices (:class:`raspv_spv.sprite_models.SpriteBank`, or a
        PhospheneSprites message's); :class:`AtlasTooLarge` when it does not fit ``max_side``."""
        import scipy.sparse as sp     # here, not at the top: the headset bridge builds atlases from messages only

        rows, cols = -(-height // scale), -(-width // scale)
        parts = [_patches(sp.csc_matrix(coarse), cols, grid=0)]
        if fine is not None and fine.nnz:
            parts.append(_patches(sp.csc_matrix(fine), width, grid=1))
        table = np.concatenate([p[0] for p in parts])
        atlas_w, atlas_h = _pack(table, max_side)
        atlas = np.zeros((atlas_h, atlas_w), np.float32)
        offset = 0
        for _, (ys, xs, vals), counts in parts:
            t = table[offset:offset + len(counts)]
            offset += len(counts)
            # each entry's place: its patch's atlas corner + (its pixel − the patch's corner)
            which = np.repeat(np.arange(len(counts)), counts)
            atlas[t[which, 7] + ys - t[which, 3], t[which, 6] + xs - t[which, 2]] = vals
        atlas = atlas.astype(np.float16).astype(np.float32)     # what travels (half floats) is what is drawn
        return cls(map_id, width, height, scale, levels, num_levels, green, table, atlas)

    def render(self, weights: np.ndarray, sprite_levels: np.ndarray | None = None) -> np.ndarray:
        """(H, W) uint8: what a client draws for one frame's ``weights`` (N,) — the reference the
        browser's WebGL drawing is checked against (and equal to the server's renderer)."""
        columns, w = drawn_columns(weights, sprite_levels, self.levels)
        by_column = dict(zip(columns.tolist(), w.tolist()))
        rows, cols = self.coarse_shape
        grids = [np.zeros((rows, cols), np.float32), np.zeros((self.height, self.width), np.float32)]
        for col, grid, x, y, pw, ph, ax, ay in self.patches:
            weight = by_column.get(int(col))
            if weight:
                grids[grid][y:y + ph, x:x + pw] += np.float32(weight) * self.atlas[ay:ay + ph, ax:ax + pw]
        image = grids[0]
        if self.scale > 1:
            image = cv2.resize(image, (cols * self.scale, rows * self.scale), interpolation=cv2.INTER_LINEAR)
            image = image[:self.height, :self.width]
        return cv2.convertScaleAbs(image + grids[1])


def _patches(m: sp.csc_matrix, grid_width: int, grid: int):
    """Patch table rows (atlas position left 0) for the non-empty columns of ``m``, and each
    entry's (row, col, value) for filling the atlas, and the entries per patch."""
    counts = np.diff(m.indptr)
    cols = np.flatnonzero(counts)
    if cols.size == 0:
        return np.zeros((0, 8), np.int32), (np.zeros(0, int), np.zeros(0, int), np.zeros(0, np.float32)), counts[cols]
    ys, xs = np.divmod(m.indices[m.indptr[cols[0]]:m.indptr[cols[-1] + 1]].astype(np.int64), grid_width)
    starts = m.indptr[cols] - m.indptr[cols[0]]
    x0, x1 = np.minimum.reduceat(xs, starts), np.maximum.reduceat(xs, starts)
    y0, y1 = np.minimum.reduceat(ys, starts), np.maximum.reduceat(ys, starts)
    table = np.zeros((cols.size, 8), np.int32)
    table[:, 0], table[:, 1], table[:, 2], table[:, 3] = cols, grid, x0, y0
    table[:, 4], table[:, 5] = x1 - x0 + 1, y1 - y0 + 1
    vals = m.data[m.indptr[cols[0]]:m.indptr[cols[-1] + 1]].astype(np.float32)
    return table, (ys, xs, vals), counts[cols]


def _pack(table: np.ndarray, max_side: int) -> tuple[int, int]:
    """Shelf packing, tallest patches first: fills columns 6–7 (atlas x, y) of ``table`` in
    place; returns the atlas (width, height)."""
    if len(table) == 0:
        return 1, 1
    area = int((table[:, 4] * table[:, 5]).sum())
    width = int(min(max_side, max(int(table[:, 4].max()), 1 << int(np.ceil(np.log2(max(1.0, np.sqrt(area))))))))
    x = y = shelf = 0
    for i in np.argsort(-table[:, 5], kind="stable"):
        w, h = int(table[i, 4]), int(table[i, 5])
        if w > width:
            raise AtlasTooLarge(f"a sprite {w} px wide does not fit a {max_side}-texel atlas")
        if x + w > width:
            x, y, shelf = 0, y + shelf, 0
        table[i, 6], table[i, 7] = x, y
        x, shelf = x + w, max(shelf, h)
    height = y + shelf
    if height > max_side:
        raise AtlasTooLarge(f"the sprites need a {width}x{height} atlas; the limit is {max_side}² texels")
    return width, height


def drawn_columns(weights: np.ndarray, sprite_levels: np.ndarray | None, levels: int) -> tuple[np.ndarray, np.ndarray]:
    """(columns, weights) of the sprites drawn for per-phosphene ``weights`` and, when the bank has
    one sprite per level (``levels`` > 1), ``sprite_levels`` (0: not drawn)."""
    w = np.asarray(weights, dtype=np.float32)
    if levels == 1:
        on = np.flatnonzero(w > 0)
        return on, w[on]
    lv = np.asarray(sprite_levels, dtype=np.int64)
    on = np.flatnonzero((lv > 0) & (w > 0))
    return on * levels + np.minimum(lv[on], levels) - 1, w[on]


def frame_weights(brightness: np.ndarray, sprite_levels: np.ndarray | None, levels: int,
                  num_levels: int) -> np.ndarray:
    """Each phosphene's weight for its sprite: its brightness, or, with one sprite per level,
    the gain on its level's sprite (brightness / (level / (N_L − 1)), as the renderer draws it)."""
    b = np.asarray(brightness, dtype=np.float32)
    if levels == 1 or sprite_levels is None or len(sprite_levels) != len(b):
        return b
    lv = np.asarray(sprite_levels, dtype=np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(lv > 0, b / (lv / np.float32(num_levels - 1)), 0.0).astype(np.float32)


def atlas_of_renderer(renderer, num_levels: int, map_id: int = 0,
                      max_side: int = MAX_ATLAS_SIDE) -> "SpriteAtlas":
    """The atlas of a :class:`~raspv_spv.renderer.Renderer`'s sprites (dropped phosphenes empty)."""
    return SpriteAtlas.from_matrices(renderer.matrix, renderer.fine, renderer.width, renderer.height, renderer.scale,
                                     renderer.levels, num_levels, map_id, renderer.output_format == "green", max_side)
