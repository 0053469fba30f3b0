"""``raspv_msgs/PhospheneSprites`` ↔ :class:`~raspv_spv.sprite_atlas.SpriteAtlas` (no rclpy:
message classes only).

The spv node publishes its simulator's sprite atlas (latched, with every new map) so that a
client can draw a frame from its per-phosphene brightness alone (the headset bridge's levels
stream, :mod:`raspv_hmd.levels_stream`) and the bridge can draw the no-data ring itself while the
spv node is gone (:meth:`SpriteAtlas.render`). The atlas travels as half floats: 1–3.5 MB for
the shipped presets at 800 px.
"""
from __future__ import annotations

import array

import numpy as np
from raspv_msgs.msg import PhospheneSprites
from std_msgs.msg import Header

from raspv_spv.sprite_atlas import SpriteAtlas


def sprites_to_msg(atlas: SpriteAtlas | None, header: Header, map_id: int, unavailable: str = "") -> PhospheneSprites:
    """The message of ``atlas`` (None: only ``unavailable``, the reason there is none)."""
    msg = PhospheneSprites(header=header, map_id=map_id, unavailable=unavailable)
    if atlas is None:
        return msg
    rows, cols = atlas.coarse_shape
    msg.width, msg.height, msg.scale, msg.coarse_width, msg.coarse_height = (atlas.width, atlas.height, atlas.scale,
                                                                             cols, rows)
    msg.levels, msg.num_levels, msg.output_format = atlas.levels, atlas.num_levels, "green" if atlas.green else "mono8"
    msg.patches = array.array("i", np.ascontiguousarray(atlas.patches, np.int32).tobytes())
    msg.atlas_height, msg.atlas_width = atlas.atlas.shape
    msg.atlas = array.array("H", atlas.atlas.astype(np.float16).view(np.uint16).tobytes())
    return msg


def atlas_from_msg(msg: PhospheneSprites) -> SpriteAtlas:
    """The atlas of a message; ValueError when it has none or is inconsistent."""
    if msg.unavailable:
        raise ValueError(msg.unavailable)
    patches = np.asarray(msg.patches, np.int32)
    texels = np.asarray(msg.atlas, np.uint16)
    if patches.size % 8 or texels.size != msg.atlas_width * msg.atlas_height or msg.scale < 1 or msg.levels < 1:
        raise ValueError(f"inconsistent PhospheneSprites of map {msg.map_id}")
    table = patches.reshape(-1, 8)
    atlas = texels.view(np.float16).astype(np.float32).reshape(msg.atlas_height, msg.atlas_width)
    if len(table) and (table[:, 6] + table[:, 4] > msg.atlas_width).any() or \
            len(table) and (table[:, 7] + table[:, 5] > msg.atlas_height).any():
        raise ValueError(f"PhospheneSprites of map {msg.map_id}: a patch lies outside the atlas")
    return SpriteAtlas(msg.map_id, msg.width, msg.height, msg.scale, msg.levels, msg.num_levels,
                       msg.output_format == "green", table, atlas)
