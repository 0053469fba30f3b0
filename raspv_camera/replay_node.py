"""`replay` node: a recorded bag as the graph's source.

Publishes the bag's messages — serialised bytes unchanged — on their topics (after remapping)
with their original timing, using the same QoS classes as the live graph
(:func:`raspv_bags.playback.publisher_qos`), and the bag's time on ``/clock``. Transforms: the
recording's ``/tf`` less the frames ``tf_exclude`` names (a pose node of the graph owns them), its
``/tf_static`` as one merged message, or — a recording without one — the camera mounting
``base_link → camera_link → <image frame>`` (:mod:`raspv_bags.replayed_tf`). The
playback itself is :class:`raspv_bags.playback.Player`, run in a thread; the executor
keeps serving parameters (``rate``, ``paused``, ``loop`` change while playing). At the end
(or on shutdown) it logs the messages sent and the timing error (p50/p95/max).
"""
from __future__ import annotations

import sys
import threading
import time

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from raspv_bags.playback import PlaybackOptions, PlaybackReport, Player, parse_remap, publisher_qos
from raspv_bags.reader import BagError
from raspv_bags.replayed_tf import ReplayedTf, header_frame_id
from raspv_camera.replay_params import PARAMS
from raspv_common import topics
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import EVENT_QOS, LATCHED_QOS, SENSOR_QOS, TF_STATIC_QOS
from raspv_common.ros_introspection import message_class

_CLASS_QOS = {"sensor": SENSOR_QOS, "latched": LATCHED_QOS, "event": EVENT_QOS}
CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)


def _profile(kind: str, spec) -> QoSProfile:
    if kind in _CLASS_QOS:
        return _CLASS_QOS[kind]
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=spec.depth,
                      reliability=ReliabilityPolicy.RELIABLE if spec.reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if spec.transient_local else DurabilityPolicy.VOLATILE)


class ReplayNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("replay", PARAMS)
        p = self.params
        if not p["bag"]:
            raise ConfigurationError("parameter 'bag' is required (a bag directory or a .mcap/.db3 file)")
        try:
            options = PlaybackOptions(rate=p["rate"], start_offset_s=p["start_offset"], loop=p["loop"],
                                      topics=tuple(t for t in p["topics"] if t),
                                      exclude=tuple(t for t in p["exclude_topics"] if t),
                                      remap=parse_remap(r for r in p["remap"] if r),
                                      clock_rate_hz=p["clock_rate"] if p["publish_clock"] else 0.0)
            self.player = Player(p["bag"], options, self._publish,
                                 self._publish_clock if p["publish_clock"] else None)
        except (BagError, ValueError) as exc:
            raise ConfigurationError(str(exc)) from None
        self.publishers_by_topic = {}
        for t in list(self.player.topics):
            out = self.player.out_topic[t.name]
            try:
                cls = message_class(t.msgtype)
            except ValueError:
                self.player.drop_topics([t.name], f"message type {t.msgtype} is not installed")
                continue
            kind, spec = publisher_qos(out, t.qos)
            self.publishers_by_topic[out] = self.create_publisher(cls, out, _profile(kind, spec))
        if not self.publishers_by_topic:
            self.player.reader.close()
            raise ConfigurationError(f"{p['bag']}: none of its message types are installed; nothing to replay")
        self.pub_clock = self.create_publisher(Clock, topics.CLOCK, CLOCK_QOS) if p["publish_clock"] else None
        self.replayed_tf = ReplayedTf(p["tf_exclude"])
        self._mounting_from = None          # a recording without /tf_static: its first image's frame is mounted
        if topics.TF_STATIC not in self.publishers_by_topic:
            from tf2_msgs.msg import TFMessage
            self.publishers_by_topic[topics.TF_STATIC] = self.create_publisher(TFMessage, topics.TF_STATIC,
                                                                                TF_STATIC_QOS)
            self._mounting_from = {topics.CAMERA_INFO: "sensor_msgs/msg/CameraInfo",
                                   topics.COLOR: "sensor_msgs/msg/Image", topics.DEPTH: "sensor_msgs/msg/Image"}
        for note in self.player.notes:
            self.get_logger().warning(note)
        r = self.player.reader
        self.get_logger().info(
            f"replaying {p['bag']}: {r.duration_s:.1f} s, {len(self.publishers_by_topic)} topics "
            f"({', '.join(sorted(self.publishers_by_topic))}), rate {p['rate']:g}"
            + (", looping" if p["loop"] else ""))
        self.report: PlaybackReport | None = None
        self._status_t = 0.0
        self._reported = False
        if p["paused"]:
            self.player.set_paused(True)
            self.announce_source("paused")      # a known pause: consumers hold the last frame
        self.create_timer(2.0, self._check_other_publishers)
        self._checks_left = 3
        self._thread = threading.Thread(target=self._play, name="replay", daemon=True)
        self._thread.start()

    # -- playback thread ----------------------------------------------------------------------
    def _publish(self, topic: str, _msgtype: str, data) -> None:
        data = data if isinstance(data, bytes) else bytes(data)
        if topic == topics.TF:
            data = self.replayed_tf.tf(data)
        elif topic == topics.TF_STATIC:
            data = self.replayed_tf.tf_static(data)
        elif self._mounting_from is not None and topic in self._mounting_from:
            frame = header_frame_id(data, self._mounting_from[topic])
            self._mounting_from = None
            self._send(self.publishers_by_topic[topics.TF_STATIC], self.replayed_tf.mounting(
                frame, self.get_clock().now().nanoseconds))
        if data is not None:
            self._send(self.publishers_by_topic[topic], data)
        if self.params["progress"]:
            self._print_status()

    def _publish_clock(self, bag_ns: int) -> None:
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(int(bag_ns), 1_000_000_000)
        self._send(self.pub_clock, msg)

    def _send(self, publisher, msg) -> None:
        """Publish; when Ctrl-C (SIGINT/SIGTERM) shut the context down between two messages,
        stop the playback instead: rclpy then refuses to publish ("publisher's context is
        invalid"), and a clean stop is not an error."""
        try:
            publisher.publish(msg)
        except Exception:
            if self.context.ok():
                raise
            self.player.stop()

    def _wait_before_start(self) -> None:
        """``delay``, then ``wait_for_subscribers`` (at most 30 s), unless stopped meanwhile."""
        if self.params["delay"] > 0 and self.player.wait_stop(self.params["delay"]):
            return
        need = self.params["wait_for_subscribers"]
        deadline = time.monotonic() + 30.0
        while need and not self.player.stop_requested:
            have = sum(p.get_subscription_count() for p in self.publishers_by_topic.values())
            if have >= need:
                return
            if time.monotonic() > deadline:
                self.get_logger().warning(f"only {have} of {need} subscriptions after 30 s; starting anyway")
                return
            self.player.wait_stop(0.05)

    def _play(self) -> None:
        self._wait_before_start()
        try:
            self.report = self.player.run()
        except Exception as exc:  # a reading failure the reader could not absorb
            self.get_logger().error(f"playback stopped: {exc}")
            self.report = None
        if not self.player.stop_requested:
            self.announce_source("down")        # the end of the recording: nothing more will come
            self._log_report()
            if self.params["at_end"] == "exit":
                self.context.try_shutdown()

    def _print_status(self) -> None:
        now = time.monotonic()
        if now - self._status_t < 0.5:
            return
        self._status_t = now
        total = sum(self.player.counts.values())
        print(f"\r[replay] {self.player.position_s:6.1f} / {self.player.reader.duration_s:.1f} s  "
              f"{total} messages  rate {self.player.rate:g}\x1b[K", end="", file=sys.stderr, flush=True)

    def _log_report(self) -> None:
        if self._reported or self.report is None:
            return
        self._reported = True
        rep = self.report
        if self.params["progress"]:
            print(file=sys.stderr)
        counts = ", ".join(f"{t} {n}" for t, n in sorted(rep.counts.items()))
        end = "stopped" if rep.stopped else "finished"
        self._say("info", f"{end}: {sum(rep.counts.values())} messages in {rep.wall_s:.1f} s "
                          f"({rep.loops} pass{'es' if rep.loops > 1 else ''}; {counts})")
        self._say("info", rep.timing.line())
        for note in rep.notes:
            if note not in self.player.reader.notes:
                self._say("warning", note)

    def _say(self, level: str, text: str) -> None:
        """The ROS logger while the context lives; after Ctrl-C shut it down, plain stderr (the
        logger would add "Failed to publish log message to rosout" to every line)."""
        if not self.context.ok():
            print(f"[{level.upper()}] [{self.get_name()}]: {text}", file=sys.stderr, flush=True)
        elif level == "warning":      # one call site per severity: rclpy refuses a change between calls
            self.get_logger().warning(text)
        else:
            self.get_logger().info(text)

    # -- graph checks and parameters -----------------------------------------------------------
    def _check_other_publishers(self) -> None:
        if self._checks_left <= 0:
            return
        self._checks_left -= 1
        for topic in self.publishers_by_topic:
            if topic in (topics.TF, topics.TF_STATIC):       # every node that owns a transform publishes these
                continue
            n = self.count_publishers(topic)
            if n > 1:
                self.warn_throttled(f"dup:{topic}", f"{topic} is also published by {n - 1} other node(s); "
                                                    f"exclude it from the replay (exclude_topics) or stop that node",
                                    period_s=1e9)

    def on_parameters(self, changes):
        if "rate" in changes:
            self.player.set_rate(changes["rate"])
        if "paused" in changes:
            self.player.set_paused(changes["paused"])
            self.announce_source("paused" if changes["paused"] else "delivering")
        if "loop" in changes:
            self.player.options.loop = changes["loop"]
        return None

    def close(self) -> None:
        self.player.stop()
        self._thread.join(timeout=5.0)
        if self.report is not None:
            self._log_report()


def main(argv=None) -> None:
    run_node(ReplayNode, argv, priority="source")


if __name__ == "__main__":
    main()
