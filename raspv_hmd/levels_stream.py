"""The levels stream: a phosphene frame as one weight per phosphene, drawn by the client from a
sprite atlas it received once (no rclpy).

A phosphene image is ``saturate(upsample(C @ w) + F @ w)`` (:class:`raspv_spv.renderer.Renderer`):
each phosphene's sprite is a fixed patch of pixels scaled by its weight. So the client needs the
patches once per map (:class:`SpriteAtlas`: every sprite's bounding box on its grid, packed into
one texture, ~1–2 MB as half floats for 1000 Gaussian phosphenes) and then, per frame, only the
weights: ``2·N`` bytes (2 kB for 1000 phosphenes, against 90 kB of PNG or 640 kB of raw pixels at
800×800). The browser client draws them with WebGL (``client/levels_renderer.js``): one quad per
lit sprite, summed in a float framebuffer, upsampled bilinearly, saturated to 8 bits — the same
arithmetic as the server's renderer (agreement checked in chromium, tests/hmd/test_levels_stream*).

Messages (little-endian; the reference is docs/hmd.md "Levels stream"):

- sprites (binary, sent before the first frame of a new map): :data:`SPRITES_HEADER`, then
  ``patches`` × 8 int32 (column, grid 0 coarse / 1 fine, x, y, w, h on that grid, atlas x, atlas y),
  then the atlas, ``atlas_h × atlas_w`` float16 (sprite values, 255 at full brightness), then
  u32 ``N`` and N uint8: the no-data ring's phosphenes (1), which the client blinks itself when
  frames stop (``N`` = 0: no ring known);
- a frame: the usual frame header (:data:`raspv_hmd.protocol.FRAME_HEADER`, format
  :data:`~raspv_hmd.protocol.FORMAT_LEVELS`), then :data:`LEVELS_HEADER` and ``N`` uint16 weights
  (weight × :data:`WEIGHT_SCALE`) and, for sprite models with one sprite per level, ``N`` uint8
  sprite levels (0: not drawn; column ``i·levels + level − 1``), then, with flag
  :data:`FRAME_OFFSET`, the field's offset on the display (i16 dx right, i16 dy down, px: eye gaze,
  spv ``gaze_mode``): the image is drawn translated by it, black where nothing moved in.
"""
from __future__ import annotations

import struct

import numpy as np

from raspv_hmd import protocol as P
from raspv_spv.sprite_atlas import SpriteAtlas

SPRITES_MAGIC = b"RSPS"
#   magic, version u8, levels u8, flags u8 (1: green output), num_levels u8, map_id u32, width u32,
#   height u32, scale u32, coarse width u32, coarse height u32, patches u32, atlas width u32, atlas height u32
SPRITES_HEADER = struct.Struct("<4sBBBBIIIIIIIII")
#   map_id u32, count u32, levels u8 (sprites per phosphene), flags u8 (FRAME_*), 2 pad bytes
LEVELS_HEADER = struct.Struct("<IIBBxx")
WEIGHT_SCALE = 16384.0          # weights travel as uint16: 0 … 4 in steps of 6e-5 (≤ 0.02 grey levels)
FRAME_FALLBACK = 1              # the frame shows a fallback, not the configured mode (stale inputs)
FRAME_NO_DATA = 2               # the frame is the no-data ring
FRAME_OFFSET = 4                # the payload ends with the field's offset: i16 dx, i16 dy [px] (eye gaze)
OFFSET_TRAILER = struct.Struct("<hh")


def sprites_message(atlas: SpriteAtlas, ring: np.ndarray | None = None) -> bytes:
    """The sprites message of ``atlas`` and the no-data ring's phosphenes ``ring`` ((N,) bool,
    :func:`raspv_spv.no_data.ring_mask`: the client draws the ring itself when frames stop
    coming — the bridge gone — instead of freezing on the last one). See the module docstring."""
    h, w = atlas.atlas.shape
    rows, cols = atlas.coarse_shape
    ring = np.zeros(0, np.uint8) if ring is None else np.asarray(ring, bool).astype(np.uint8)
    head = SPRITES_HEADER.pack(SPRITES_MAGIC, P.PROTOCOL_VERSION, atlas.levels, int(atlas.green), atlas.num_levels,
                               atlas.map_id, atlas.width, atlas.height, atlas.scale, cols, rows, len(atlas.patches),
                               w, h)
    return (head + atlas.patches.astype("<i4").tobytes() + atlas.atlas.astype("<f2").tobytes()
            + struct.pack("<I", ring.size) + ring.tobytes())


def parse_sprites_message(data: bytes | memoryview) -> tuple[SpriteAtlas, np.ndarray]:
    """A sprites message → (the atlas, the ring's phosphenes (N,) bool, maybe empty);
    ProtocolError when inconsistent."""
    if len(data) < SPRITES_HEADER.size:
        raise P.ProtocolError("bad_sprites", "sprites message shorter than its header")
    (magic, version, levels, flags, num_levels, map_id, width, height, scale, _cols, _rows, n,
     aw, ah) = SPRITES_HEADER.unpack_from(data)
    at = SPRITES_HEADER.size + 32 * n + 2 * aw * ah
    ring_n = struct.unpack_from("<I", data, at)[0] if len(data) >= at + 4 else -1
    if magic != SPRITES_MAGIC or version != P.PROTOCOL_VERSION or ring_n < 0 or len(data) != at + 4 + ring_n:
        raise P.ProtocolError("bad_sprites", f"not a protocol-{P.PROTOCOL_VERSION} sprites message "
                                             f"(magic {bytes(magic)!r}, {len(data)} bytes)")
    table = np.frombuffer(data, "<i4", 8 * n, SPRITES_HEADER.size).reshape(n, 8).astype(np.int32)
    atlas = np.frombuffer(data, "<f2", aw * ah, SPRITES_HEADER.size + 32 * n).reshape(ah, aw).astype(np.float32)
    ring = np.frombuffer(data, np.uint8, ring_n, at + 4).astype(bool)
    return SpriteAtlas(map_id, width, height, scale, levels, num_levels, bool(flags & 1), table, atlas), ring


def pack_levels_payload(map_id: int, weights: np.ndarray, sprite_levels: np.ndarray | None, levels: int,
                        flags: int = 0, offset_px: tuple[int, int] = (0, 0)) -> bytes:
    """The payload of a levels frame (after the frame header); a non-zero field ``offset_px``
    (dx right, dy down, whole px: eye gaze) is appended with :data:`FRAME_OFFSET` set."""
    w = np.asarray(weights, dtype=np.float32)
    q = np.clip(np.rint(np.nan_to_num(w) * WEIGHT_SCALE), 0, 65535).astype("<u2")
    dx, dy = (max(-32768, min(32767, int(v))) for v in offset_px)
    if dx or dy:
        flags |= FRAME_OFFSET
    out = LEVELS_HEADER.pack(map_id, len(w), levels, flags) + q.tobytes()
    if levels > 1:
        out += np.asarray(sprite_levels if sprite_levels is not None else np.zeros(len(w)), dtype=np.uint8).tobytes()
    if flags & FRAME_OFFSET:
        out += OFFSET_TRAILER.pack(dx, dy)
    return out


def unpack_levels_payload(data: bytes | memoryview) -> tuple[int, np.ndarray, np.ndarray | None, int]:
    """(map_id, weights (N,) float32, sprite levels or None, flags) of a levels frame's payload
    (the field offset: :func:`levels_offset`)."""
    if len(data) < LEVELS_HEADER.size:
        raise P.ProtocolError("bad_frame", "levels payload shorter than its header")
    map_id, n, levels, flags = LEVELS_HEADER.unpack_from(data)
    need = LEVELS_HEADER.size + 2 * n + (n if levels > 1 else 0) + (OFFSET_TRAILER.size if flags & FRAME_OFFSET else 0)
    if len(data) != need:
        raise P.ProtocolError("bad_frame", f"levels payload of {len(data)} bytes for {n} phosphenes (expected {need})")
    w = np.frombuffer(data, "<u2", n, LEVELS_HEADER.size).astype(np.float32) / np.float32(WEIGHT_SCALE)
    lv = np.frombuffer(data, np.uint8, n, LEVELS_HEADER.size + 2 * n).copy() if levels > 1 else None
    return map_id, w, lv, flags


def levels_offset(data: bytes | memoryview) -> tuple[int, int]:
    """The field offset (dx right, dy down) [px] of a levels payload ((0, 0) without one)."""
    flags = LEVELS_HEADER.unpack_from(data)[3]
    return OFFSET_TRAILER.unpack_from(data, len(data) - OFFSET_TRAILER.size) if flags & FRAME_OFFSET else (0, 0)
