"""What the wearer saw, re-rendered from a recording without ``/spv/image`` (no rclpy).

The spv node publishes with every display frame each phosphene's brightness and the sprite it is
drawn with (``/spv/frame``), and, latched, the sprite atlas of its phosphene map
(``/spv/sprites``): what the headset page draws the view from. A recording keeps those by
default and leaves out the rendered image (800×800 at 50 Hz: ~32 MB/s,
:data:`raspv_bags.recording.IMAGE_TOPICS`); :func:`shown_images` draws each recorded frame
again with :meth:`raspv_spv.sprite_atlas.SpriteAtlas.render` — the bridge's and the page's
reference drawing, equal to the spv node's renderer within one grey level (the atlas travels as
half floats) — shifted by the frame's gaze offset, green when the device is. ``raspv render BAG
--shown`` writes them as a video.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from raspv_bags.message_types import typestore
from raspv_bags.shown_frames import FRAME_TOPIC, _decode_type
from raspv_spv.gaze import shift_image
from raspv_spv.sprite_atlas import frame_weights

SPRITES_TOPIC = "/spv/sprites"


class ShownRenderError(ValueError):
    """A recording the wearer's view cannot be re-rendered from (one line: what is missing)."""


@dataclass(frozen=True)
class ShownImage:
    stamp: float          # the display frame's stamp [s]
    image: np.ndarray     # (H, W) uint8, or (H, W, 3) with only green for a green device
    mode: str             # what was shown (the mode, a fallback, or no_data)


def shown_images(reader) -> Iterator[ShownImage]:
    """The wearer's view of every ``/spv/frame`` of an open :class:`~raspv_bags.reader.BagReader`
    whose map's sprites (``/spv/sprites``) are in the bag, in recording order."""
    from raspv_spv.sprites_msg import atlas_from_msg      # message fields only (no rclpy)

    for topic in (FRAME_TOPIC, SPRITES_TOPIC):
        if topic not in reader.topics:
            raise ShownRenderError(f"{reader.path}: no {topic} in this recording: the wearer's view cannot be "
                                   f"re-rendered (record {FRAME_TOPIC} and {SPRITES_TOPIC}; render from the camera "
                                   f"streams without --shown)")
    store = typestore()
    atlases = {}
    for m in reader.messages([SPRITES_TOPIC]):
        msg = store.deserialize_cdr(bytes(m.data), m.msgtype)
        try:
            atlases[int(msg.map_id)] = atlas_from_msg(msg)
        except ValueError as exc:
            reader.notes.append(f"{SPRITES_TOPIC}: map {msg.map_id}: {exc}")
    frame_type = _decode_type(reader.topics[FRAME_TOPIC].definition)
    for m in reader.messages([FRAME_TOPIC]):
        f = store.deserialize_cdr(bytes(m.data), frame_type)
        atlas = atlases.get(int(f.map_id))
        if atlas is None:
            continue                                   # a map whose sprites were not recorded
        brightness = np.asarray(f.brightness, np.float32)
        sprite_levels = np.asarray(f.sprite_levels, np.uint8) if len(getattr(f, "sprite_levels", ())) else None
        image = atlas.render(frame_weights(brightness, sprite_levels, atlas.levels, atlas.num_levels), sprite_levels)
        image = shift_image(image, int(round(getattr(f, "field_offset_x_px", 0.0))),
                            int(round(getattr(f, "field_offset_y_px", 0.0))))
        if atlas.green:
            image = np.stack([np.zeros_like(image), image, np.zeros_like(image)], axis=2)
        yield ShownImage(f.header.stamp.sec + 1e-9 * f.header.stamp.nanosec, image, f.mode)
