"""The bridge's frames (ROS side): from the spv node to the headset server, in the form each
client wants, and the no-data ring while the spv node is gone.

- Levels clients (the browser client): ``/spv/frame`` → per-phosphene weights
  (:mod:`raspv_hmd.levels_stream`), with the sprite atlas of the latched ``/spv/sprites`` sent to
  each client once per map. About 2 kB per frame.
- Image clients (native, TCP, ``format=raw|png``): ``/spv/image``, subscribed only while such a
  client is connected — the spv node renders images only while someone subscribes, so a graph
  whose only client draws the levels stream renders no image at all.
- The spv node gone (killed, stopped, restarting: its DDS liveliness lost, or no frame for the
  stale bound of :mod:`raspv_spv.staleness`): the bridge draws the blinking no-data ring itself
  from the latched ``/spv/map`` and ``/spv/sprites``, so a headset never shows a frozen or black
  image while the spv node restarts. For :data:`PROBATION_S` after its frames come back, the
  spv node's frames are judged by their gaps alone (the crash detector's bound, ≤ 0.26 s), even
  though its new process lives: a replacement that sends its first frames and then stalls while
  it starts (its first camera frame, caches) showed a frozen image for 346–424 ms in 2 of 45
  kills under load, the 1-s late bound of a live producer applying.

The frame path runs on a lean node of its own (``<bridge>_frames``: only these subscriptions
and one timer, no parameter services) spun by its own executor in a thread: rclpy's executor
costs per wake-up grow with the entities it waits on, and with the bridge's services, timers and
clients in one wait set the 50 Hz frames took 27 % of a core.

A mixin of :class:`raspv_hmd.bridge_node.BridgeNode`.
"""
from __future__ import annotations

import threading
import time

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from raspv_msgs.msg import PhospheneFrame, PhospheneMap, PhospheneSprites
from sensor_msgs.msg import Image

from raspv_common import topics
from raspv_common.conversions import ImageEncodingError, image_to_array, stamp_to_seconds
from raspv_common.liveliness import ProducerWatch
from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown
from raspv_common.qos import LATCHED_QOS, SENSOR_QOS
from raspv_hmd.levels_stream import FRAME_FALLBACK, FRAME_NO_DATA, pack_levels_payload, sprites_message
from raspv_spv import staleness
from raspv_spv.no_data import NoDataPattern
from raspv_spv.sprite_atlas import SpriteAtlas, frame_weights
from raspv_spv.sprites_msg import atlas_from_msg

SPV_INPUT = "phosphenes"          # the spv node's frames, watched like an input
RING_PERIOD_S = 0.05              # the bridge's own no-data ring: 20 frames/s (it blinks at 2 Hz)
PROBATION_S = 3.0                 # after the ring: the returning spv node's gaps judged as a crash's for this long [s]
WATCH_LATE_S = 0.25               # the ring's check this much later than its period is logged (the frame thread held up)


class BridgeFrames:
    """Frames from the spv node to the clients (see the module docstring)."""

    def _setup_frames(self) -> None:
        self.frames = self.images = 0                        # /spv/frame and /spv/image messages in
        self._atlas: SpriteAtlas | None = None             # the sprites of the current map
        self._map_msg: PhospheneMap | None = None
        self._ring: tuple[int, NoDataPattern] | None = None   # (map id, pattern)
        self._ring_shown = False
        self._probation_until = float("-inf")              # monotonic time; see PROBATION_S
        self._watched_at: float | None = None              # the ring check's last run (monotonic)
        self._image_sub = None
        self.spv_frames = staleness.StalenessMonitor(frozenset({SPV_INPUT}))
        self.spv_frames.watch({SPV_INPUT})
        self.spv_producer = ProducerWatch(self)
        self.spv_producer.watch({SPV_INPUT: topics.SPV_FRAME})
        self.create_subscription(PhospheneSprites, topics.SPV_SPRITES, self.on_sprites, LATCHED_QOS)
        self.create_subscription(PhospheneMap, topics.SPV_MAP, self.on_map, LATCHED_QOS)
        # the hot path: its own lean node and executor (see the module docstring)
        self._frames_node = rclpy.create_node(f"{self.get_name()}_frames", context=self.context,
                                              start_parameter_services=False, enable_rosout=False)
        self._frames_node.create_subscription(PhospheneFrame, topics.SPV_FRAME, self.on_frame, SENSOR_QOS)
        self._frames_node.create_timer(RING_PERIOD_S, self._watch_spv)
        self._clients_changed = self._frames_node.create_guard_condition(self._follow_clients)
        self._frames_executor = SingleThreadedExecutor(context=self.context)
        self._frames_executor.add_node(self._frames_node)
        self._frames_thread = threading.Thread(target=self._spin_frames, name="bridge-frames", daemon=True)
        self._frames_thread.start()

    def _spin_frames(self) -> None:
        try:
            while self.context.ok():
                self._frames_executor.spin_once(timeout_sec=0.5)
        except SHUTDOWN_ERRORS as exc:              # shutting down; anything else is a bug: it shows
            if not during_shutdown(exc, self.context):   # (a RuntimeError swallowed here once ended the
                raise                                    # thread silently: a headset without frames or ring)

    def _close_frames(self) -> None:
        """Stop the frames thread, then destroy its node (never while its executor waits on it)."""
        executor = getattr(self, "_frames_executor", None)
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)      # wakes its wait; spin_once then raises ShutdownException
            self._frames_thread.join(timeout=2.0)
            if not self._frames_thread.is_alive():
                self._frames_node.destroy_node()

    # -- which frames the clients need ------------------------------------------------------------
    def _follow_clients(self) -> None:
        """Subscribe to ``/spv/image`` while a client needs images, and only then."""
        server = getattr(self, "server", None)
        wants = server is not None and server.wants_images
        if wants and self._image_sub is None:
            self._image_sub = self._frames_node.create_subscription(Image, topics.SPV_IMAGE, self.on_image, SENSOR_QOS)
        elif not wants and self._image_sub is not None:
            self._frames_node.destroy_subscription(self._image_sub)
            self._image_sub = None

    def on_image(self, msg: Image) -> None:
        if msg.encoding not in ("mono8", "rgb8"):
            self.warn_throttled("encoding", f"ignoring {topics.SPV_IMAGE} in {msg.encoding!r}; expected mono8 or rgb8")
            return
        try:
            image = image_to_array(msg)
        except ImageEncodingError as exc:
            self.warn_throttled("image", f"ignoring a broken {topics.SPV_IMAGE} message: {exc}")
            return
        stamp = stamp_to_seconds(msg.header.stamp) or time.time()
        self.server.submit_frame(image, stamp)
        self.images += 1

    # -- levels stream ----------------------------------------------------------------------------
    def on_sprites(self, msg: PhospheneSprites) -> None:
        try:
            atlas = atlas_from_msg(msg)
        except ValueError as exc:
            self._atlas = None
            self.server.levels_unavailable(str(exc))
        else:
            self._atlas = atlas
            self._offer_sprites()
        self._clients_changed.trigger()

    def on_map(self, msg: PhospheneMap) -> None:
        self._map_msg = msg
        self._offer_sprites()
        self.server.show_view(width=int(msg.width), height=int(msg.height), focal_px=float(msg.focal_px),
                              spacing_px=float(msg.spacing_x_px), fov_deg=float(msg.fov_deg))   # gaze from a point

    def _offer_sprites(self) -> None:
        """Hand the clients the atlas of the current map with its no-data ring (both latched
        topics in, either order)."""
        atlas, ring = self._atlas, self._ring_pattern()
        if atlas is not None and ring is not None and ring[0] == atlas.map_id:
            self.server.submit_sprites(atlas.map_id, sprites_message(atlas, ring[1].mask))

    def on_frame(self, msg: PhospheneFrame) -> None:
        now = time.monotonic()
        self.spv_frames.arrived(SPV_INPUT, now)
        self.spv_producer.arrived(SPV_INPUT)
        self.frames += 1
        if self._ring_shown:
            self._ring_shown = False
            self._probation_until = now + PROBATION_S
            self.get_logger().info("the spv node's frames are back")
        atlas = self._atlas
        if atlas is None or msg.map_id != atlas.map_id or not self.server.wants_levels:
            return
        brightness = np.frombuffer(msg.brightness, np.float32)
        sprite_levels = np.frombuffer(msg.sprite_levels, np.uint8) if len(msg.sprite_levels) else None
        flags = (FRAME_NO_DATA if msg.mode == staleness.NO_DATA else 0) | (
            FRAME_FALLBACK if msg.configured_mode and msg.mode != msg.configured_mode else 0)
        offset = (int(round(msg.field_offset_x_px)), int(round(msg.field_offset_y_px)))     # eye gaze
        payload = pack_levels_payload(msg.map_id, frame_weights(brightness, sprite_levels, atlas.levels, atlas.num_levels),
                                      sprite_levels, atlas.levels, flags, offset)
        self.server.submit_levels(msg.map_id, payload, stamp_to_seconds(msg.header.stamp) or time.time(),
                                  atlas.width, atlas.height, atlas.green)

    # -- the spv node gone: the no-data ring from here ------------------------------------------------
    def _watch_spv(self) -> None:
        now = time.monotonic()
        if self._watched_at is not None and now - self._watched_at > RING_PERIOD_S + WATCH_LATE_S:
            self.warn_throttled("watch_late", f"the frame thread was held up: {now - self._watched_at:.2f} s between "
                                              f"checks of the spv node's frames (every {RING_PERIOD_S:.2f} s)")
        self._watched_at = now
        producers = self.spv_producer.states()
        on_probation = now < self._probation_until and producers.get(SPV_INPUT) == staleness.ALIVE
        if on_probation:            # a process just back: its gaps are judged alone (see PROBATION_S)
            producers = {**producers, SPV_INPUT: staleness.UNKNOWN}
        if SPV_INPUT not in self.spv_frames.check(now, producers):
            return
        ring = self._ring_pattern()
        if ring is None:
            return                                  # no map seen yet: nothing to draw the ring with
        map_id, pattern = ring
        if not self._ring_shown:
            self._ring_shown = True
            what = self.spv_frames.describe(SPV_INPUT, now, producers.get(SPV_INPUT, staleness.UNKNOWN))
            if on_probation:
                what = what[:-1] + "; its node back less than {:.0f} s ago and stalled)".format(PROBATION_S)
            self.get_logger().warning(f"no frames from the spv node ({what}): "
                                      "showing the no-data ring")
        levels = pattern.levels(now)
        num_levels = max(int(self._map_msg.num_levels), 2)
        brightness = levels.astype(np.float32) / np.float32(num_levels - 1)
        atlas = self._atlas
        if atlas is None or atlas.map_id != map_id:
            return                                  # its sprites are not in: nothing to draw with
        sprite_levels = levels if atlas.levels > 1 else None
        weights = frame_weights(brightness, sprite_levels, atlas.levels, num_levels)
        stamp = time.time()
        if self.server.wants_levels:
            payload = pack_levels_payload(map_id, weights, sprite_levels, atlas.levels, FRAME_NO_DATA)
            self.server.submit_levels(map_id, payload, stamp, atlas.width, atlas.height, atlas.green)
        if self.server.wants_images:
            image = atlas.render(weights, sprite_levels)
            self.server.submit_frame(np.stack([np.zeros_like(image), image, np.zeros_like(image)], axis=2)
                                     if atlas.green else image, stamp)

    def _ring_pattern(self):
        """(map id, pattern) of the latest map, built once per map."""
        m = self._map_msg
        if m is None:
            return None
        if self._ring is None or self._ring[0] != m.map_id:
            centres = np.stack([np.asarray(m.display_x, np.float32), np.asarray(m.display_y, np.float32)], axis=1)
            pattern = NoDataPattern(centres, np.asarray(m.dropped, bool), m.field == PhospheneMap.FIELD_CIRCULAR,
                                    max(int(m.num_levels), 2))
            self._ring = (m.map_id, pattern)
        return self._ring
