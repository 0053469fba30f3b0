"""The spv node's display (ROS side): the loop that shows a frame every 1/rate s, or at once on
new content when it follows its input (:mod:`raspv_spv.display_clock`), and the tick that
publishes ``/spv/image`` (only while someone subscribes) and ``/spv/frame``, and the latched
``/spv/map`` and ``/spv/sprites``. A mixin of :class:`raspv_spv.spv_node.SpvNode`:
it reads the node's simulator, view, staleness plan, publishers and display statistics.
"""
from __future__ import annotations

import array
import dataclasses
import time

import numpy as np
from rclpy._rclpy_pybind11 import RCLError
from sensor_msgs.msg import Image

from raspv_common.conversions import stamp_to_seconds
from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown
from raspv_common.startup_timing import startup_mark
from raspv_common.thread_priority import DISPLAY_RT_PRIORITY, raise_process_priority, raise_thread_priority
from raspv_msgs.msg import PhospheneFrame, PhospheneMap
from raspv_spv import staleness
from raspv_spv.gaze import shift_image
from raspv_spv.spv_node_frames import PHOSPHENE_FRAME
from raspv_spv.sprites_msg import sprites_to_msg

REPORT_PERIOD_S = 10.0


class SpvDisplay:
    """Display loop, tick and dropped-frame reports of the spv node."""

    def tick(self, frames: int | None = None, stamp: float | None = None) -> None:
        """One display frame (headless: ``frames`` elapsed, stamped ``stamp`` s)."""
        if not self.context.ok():                  # shutting down: the publishers are gone
            return
        t0 = time.monotonic()
        if frames is not None:
            pass
        elif self._last_tick is None:
            frames = 1
        else:
            period = 1.0 / self.params["rate"]
            frames = max(1, int(round((t0 - self._last_tick) / period)))
            self._dropped += frames - 1
        self._last_tick = t0
        header = self.header(PHOSPHENE_FRAME, stamp)
        with self._sim_lock:
            sim, map_id = self.sim, self.map_id
            plan, shown_sim, no_data = self._shown_for(sim, t0)
            scene_stamp = 0.0
            gaze = self.gaze_for_tick(sim)          # eye gaze: field offset, sampling turned (view), saccade blank
            if plan.no_data:                        # the camera stopped: the no-data pattern, not its last frame
                levels, source_stamp = no_data.levels(t0), 0.0
            else:
                shown = self.view.levels_at(shown_sim, map_id, stamp_to_seconds(header.stamp))
                if shown is None and not self._first_shown and stamp is None:
                    # inputs in, nothing computed from them yet (camera info not in, device latency):
                    # still the no-data pattern, not a black field labelled with the mode (headless
                    # runs stay deterministic: blank)
                    plan = staleness.DisplayPlan(staleness.NO_DATA, (), plan.stale, False)
                    levels, source_stamp = no_data.levels(t0), 0.0
                elif shown is None:
                    levels, source_stamp = np.zeros(sim.count, np.uint8), 0.0
                else:
                    self._first_shown = True
                    levels, shown_frame = shown
                    source_stamp = shown_frame.stamp
                    if shown_sim.mode.needs & staleness.SCENE_INPUTS:
                        scene_stamp = shown_frame.inputs.scene_stamp
            if gaze.blank:
                levels = np.zeros_like(levels)
            brightness = sim.brightness(levels, frames, at_s=t0 if stamp is None else stamp)
        if stamp is not None:
            source_stamp = stamp                    # headless: the frame answers this input
        msg = None
        if self.pub_image.get_subscription_count():          # the image only when someone watches it
            image = shift_image(sim.render(brightness), *gaze.offset_px)
            msg = Image(header=header, height=image.shape[0], width=image.shape[1], is_bigendian=0)
            msg.encoding = "mono8" if image.ndim == 2 else "rgb8"
            msg.step = image.shape[1] * (1 if image.ndim == 2 else 3)
            msg.data = array.array("B", image.tobytes())
        frame = PhospheneFrame(header=header, map_id=map_id, mode=plan.mode, overlays=list(plan.overlays),
                               configured_mode=sim.config.mode, configured_overlays=list(sim.config.overlays),
                               temporal=sim.temporal is not None, field_offset_x_px=float(gaze.offset_px[0]),
                               field_offset_y_px=float(gaze.offset_px[1]), saccade=gaze.saccade)
        frame.source_stamp = self.header("", source_stamp).stamp
        frame.scene_stamp = self.header("", scene_stamp).stamp
        frame.levels = array.array("B", levels.tobytes())
        frame.brightness = array.array("f", brightness.astype(np.float32).tobytes())
        if sim.renderer.levels > 1:                 # the sprite each phosphene is drawn with (levels stream)
            frame.sprite_levels = array.array("B", sim.sprite_levels.tobytes())
        try:
            if msg is not None:
                self.pub_image.publish(msg)
            self.pub_frame.publish(frame)
        except RCLError:
            if self.context.ok():
                raise
            return                                  # the context ended while this tick ran
        self._ticks += 1
        self._tick_ms.append(1e3 * (time.monotonic() - t0))

    def _display_loop(self) -> None:
        """Call :meth:`tick` every 1/rate s on absolute deadlines, and at once on new content
        when the display follows its input (:mod:`raspv_spv.display_clock`); after a stall it
        resumes from now (the frames missed are counted as dropped by ``tick``). The process
        starts as a normal one and takes real-time priority once the first frame computed from
        inputs is shown (:meth:`_take_realtime_priority`)."""
        realtime = False
        while self.clock.wait(1.0 / self.params["rate"], self._follows_input()):
            try:
                self.tick()
            except SHUTDOWN_ERRORS as exc:          # Ctrl-C/SIGTERM ended the context during a tick
                if during_shutdown(exc, self.context):
                    return
                raise
            if not realtime and self._first_shown:
                realtime = True
                self._take_realtime_priority()

    def _take_realtime_priority(self) -> None:
        """The display thread ahead of the node's other threads, those ahead of the graph's
        normal processes, where allowed (``raspv_common.thread_priority``)."""
        raise_thread_priority(realtime=True, rt_priority=DISPLAY_RT_PRIORITY)
        raise_process_priority()
        startup_mark("real-time priority")

    def _follows_input(self) -> bool:
        """New content is shown at once: ``display_on_input`` with the temporal model off or
        recursive (advanced by the real time of each frame; the look-up table steps in whole
        display frames) and no simulated device latency (frames wait for it)."""
        p = self.params
        model_keeps_clock = p["temporal"] and p["temporal_update"] == "lut"
        return bool(p["display_on_input"]) and not model_keeps_clock and p["device_latency_ms"] == 0

    def report(self) -> None:
        """Every 10 s: warn about dropped display frames."""
        new = self._dropped - self._dropped_reported
        if new > 0:
            rate = self.params["rate"]
            self.get_logger().warning(f"dropped {new} display frames in the last {REPORT_PERIOD_S:.0f} s at {rate:g} Hz "
                                      f"({self._dropped} since start, {self._ticks} shown)")
            self._dropped_reported = self._dropped

    def publish_map(self) -> None:
        sim, map_id = self.sim, self.map_id
        m, c = sim.map, sim.config
        msg = PhospheneMap(header=self.header(PHOSPHENE_FRAME), map_id=map_id, device=c.device.name, width=c.width,
                           height=c.height, fov_deg=c.device.fov_deg, focal_px=m.focal_px,
                           phosphene_fov_deg=c.device.phosphene_fov_deg, phosphene_diameter_px=m.diameter_px,
                           grid=PhospheneMap.GRID_HEXAGONAL if c.device.grid == "hexagonal" else PhospheneMap.GRID_RECTANGULAR,
                           field=PhospheneMap.FIELD_CIRCULAR if c.device.field == "circular" else PhospheneMap.FIELD_RECTANGULAR,
                           spacing_x_px=float(m.spacing_x), spacing_y_px=float(m.spacing_y),
                           num_levels=c.device.num_levels, dropout_ratio=c.device.dropout,
                           position_noise_px=c.device.noise_px, seed=c.seed)
        msg.x = array.array("f", m.centres[:, 0].astype(np.float32).tobytes())
        msg.y = array.array("f", m.centres[:, 1].astype(np.float32).tobytes())
        msg.display_x = array.array("f", m.display_centres[:, 0].astype(np.float32).tobytes())
        msg.display_y = array.array("f", m.display_centres[:, 1].astype(np.float32).tobytes())
        msg.dropped = [bool(d) for d in m.dropped]
        self.pub_map.publish(msg)
        atlas, unavailable = sim.sprite_atlas()
        if atlas is not None:
            atlas = dataclasses.replace(atlas, map_id=map_id)
        self.pub_sprites.publish(sprites_to_msg(atlas, msg.header, map_id, unavailable))
