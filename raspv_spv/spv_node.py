"""`spv` node: the phosphene simulator in the graph.

Inputs (only those the mode and overlays need are subscribed): colour, depth, camera info,
camera pose, scene structure and labels (from the `scene` node); with ``reprojection`` also
``/head/orientation``, ``/odom`` and ``/camera/pose``. Every new frame of the mode's main input
(colour, else depth; for scene modes the scene node's outputs) is turned into levels by the
:class:`~raspv_spv.simulator.PhospheneSimulator` with the camera pose *at the frame's stamp*
(when poses come later than the images, as from RGB-D odometry, a frame is shown at once with
the pose predicted at its stamp and recomputed when its own pose comes; ``predict_pose`` off:
it waits for its pose). Scene modes likewise show each new depth frame at once with the newest
scene result carried into it, and again with its own when that comes (``carry_scene``,
:mod:`raspv_perception.scene_carry`).
A display loop at ``rate`` Hz (50 by default; headsets 72, 90, 120) picks the frame
to show (:class:`~raspv_spv.reprojection.DisplayView`: the newest, or the one captured
``device_latency_ms`` ago), re-samples it for the newest head orientation (display-time
reprojection), advances the temporal model (the recursive model by the real time elapsed,
:mod:`raspv_spv.temporal_recursive`; the look-up table by the frames that elapsed) and publishes
``/spv/image`` and ``/spv/frame`` whatever the inputs do: it never waits for a camera frame, and
ticks it could not run on time are counted as dropped frames and reported every 10 s. With the
temporal model off or recursive (``display_on_input``) a head turn or a new frame is shown at
once instead of at the next tick (:mod:`raspv_spv.display_clock`; the loop
and the tick are in :mod:`raspv_spv.spv_node_display`).
With ``headless`` there is no display loop: each computed frame is published at once with its
input's stamp (sim time in sweeps), the temporal model advancing by the input time elapsed.
``/spv/map`` is latched and re-published whenever the map changes. A parameter change is
checked at once (map, implant layout, sprite model, mode: refused with the reason when it
cannot be built) and the new simulator — sprites and temporal table can take seconds the first
time — is built in the background (:mod:`raspv_spv.background_build`; what is not in the disk
caches by a lower-priority subprocess, :mod:`raspv_spv.prebuild`) while the old one keeps
displaying; it is swapped in between two display ticks, with levels already computed from the
latest frame, so the display never stalls (:mod:`raspv_spv.spv_node_rebuild`). Bad input images are skipped with one rate-limited
warning. Inputs that stop are noticed within 300 ms (:mod:`raspv_spv.staleness`): scene modes
fall back to ``depth``, overlays whose input stopped are dropped, a stopped camera shows the
blinking no-data ring (:mod:`raspv_spv.no_data`); ``/spv/status`` says what is shown.
"""
from __future__ import annotations

import dataclasses
import json
import statistics
import sys
from collections import deque
import threading
import time

import numpy as np
from geometry_msgs.msg import PoseStamped, QuaternionStamped
from rclpy._rclpy_pybind11 import RCLError
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMsg
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import String

from raspv_common import topics
from raspv_common.liveliness import ProducerWatch
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import LATCHED_QOS, LATEST_QOS, SENSOR_QOS
from raspv_common.thread_priority import normal_priority
from raspv_common.startup_timing import startup_mark
from raspv_msgs.msg import ClassNames, NavGuidance, PhospheneFrame, PhospheneMap, PhospheneSprites, StairDetection
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from raspv_perception.scene_carry import carry_labels, structure_seen_from
from raspv_spv import staleness
from raspv_spv.background_build import BackgroundBuilder
from raspv_spv.display_clock import DisplayClock
from raspv_spv.spv_node_display import REPORT_PERIOD_S, SpvDisplay
from raspv_spv.spv_node_gaze import SpvGaze
from raspv_spv.spv_node_inputs import SpvInputs
from raspv_spv.spv_node_frames import SpvFrames
from raspv_spv.spv_node_page import SpvPage
from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.no_data import NoDataPattern
from raspv_spv.reprojection import STAMP_TOLERANCE_S as POSE_TOLERANCE_S
from raspv_spv.reprojection import DisplayFrame, DisplayView
from raspv_spv.simulator import InputError, PhospheneSimulator
from raspv_spv.spv_node_rebuild import (_BUILD_ERRORS, SpvReconfiguration, _reason, _Rebuild, build_simulator,
                                        drawing_spec)
from raspv_spv.spv_params import PARAMS

VIEW_INPUTS = frozenset({"camera_pose", "odom", "head"})     # what display-time reprojection reads
MAX_CARRY_S = staleness.LATE_S   # carry_scene: a scene result is carried at most this far (an alive scene node's bound)
INPUT_TOPICS = {"color": topics.COLOR, "depth": topics.DEPTH, "scene": topics.SCENE_STRUCTURE,
                "scene_labels": topics.SCENE_LABELS, "nav_path": topics.NAV_PATH, "nav_guidance": topics.NAV_GUIDANCE,
                "stairs": topics.STAIRS, "segmentation": topics.SEGMENTATION_LABELS}


class SpvNode(SpvInputs, SpvDisplay, SpvGaze, SpvFrames, SpvPage, SpvReconfiguration, RaspvNode):
    def __init__(self) -> None:
        super().__init__("spv", PARAMS)
        # real time from the display's first frame from inputs (_display_loop), not for the start-up
        # (node, first depth frame: it held a running bridge's frame thread up ~0.36 s)
        self.defers_realtime = not self.params["headless"]
        try:
            with normal_priority():                 # not ahead of the other nodes starting up
                self.sim = build_simulator(self.params)
        except _BUILD_ERRORS as exc:
            raise ConfigurationError(_reason(exc)) from None
        self.map_id = 1
        self._sim_lock = threading.Lock()
        # run-time changes: checked at once, built in the background, swapped in by _swap_in
        self._applied_params = dict(self.params)
        self._requested = (drawing_spec(self.sim.config), self.map_id)
        self._swap_pending = self._map_pending = False     # ROS-side follow-ups of a swap
        self._failed: tuple[_Rebuild, Exception] | None = None
        self._builder = BackgroundBuilder(self._build, self._swap_in, self._build_failed, name="spv-build")
        self._after_build = self.create_guard_condition(self._on_build_done)
        # latest inputs and the levels computed from them
        self.color = self.depth = self.pose = None
        self.scene = self.scene_labels = None          # scene perception (scene modes)
        self.extras: dict[str, object] = {}             # further inputs by name (e.g. nav_path)
        self.stamps = {"color": 0.0, "depth": 0.0, "scene": 0.0, "scene_labels": 0.0, "stairs": 0.0}
        self._waiting_since: float | None = None
        # frames with their levels, poses, and what the display shows (reprojection, device latency)
        self.view = DisplayView(self.params["reprojection"], self.params["device_latency_ms"], self.params["camera_source"],
                                self.params["view_memory_s"])
        self._pending: FrameInputs | None = None        # a frame waiting for its camera pose
        self._pending_shown = False                     # … already shown with a predicted pose
        # stale inputs (raspv_spv.staleness): what the display shows instead
        self.staleness = staleness.StalenessMonitor()
        self.producers = ProducerWatch(self)            # whether the nodes behind the inputs live
        self._plan_lock = threading.Lock()
        self._shown: tuple | None = None        # (sim, stale set, plan, simulator shown, no-data pattern)
        self._status_args: tuple | None = None  # (plan, configured mode, producer states) /spv/status last told
        self._plan_logged = -1e9                # monotonic time of the last stale-input warning
        self._stale_logged = False
        self._seen: set[str] = set()
        # display statistics
        self._last_tick: float | None = None
        self._first_shown = False               # a frame computed from inputs was shown (else: the no-data ring)
        self._ticks = 0
        self._dropped = 0
        self._dropped_reported = 0
        self._tick_ms: deque[float] = deque(maxlen=3000)
        self.pub_image = self.create_publisher(Image, topics.SPV_IMAGE, SENSOR_QOS)
        self.pub_frame = self.create_publisher(PhospheneFrame, topics.SPV_FRAME, SENSOR_QOS)
        self.pub_map = self.create_publisher(PhospheneMap, topics.SPV_MAP, LATCHED_QOS)
        self.pub_sprites = self.create_publisher(PhospheneSprites, topics.SPV_SPRITES, LATCHED_QOS)
        self.pub_status = self.create_publisher(String, topics.SPV_STATUS, LATCHED_QOS)
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self.on_camera_info, SENSOR_QOS)
        self._subs: dict[str, object] = {}
        self._update_subscriptions(self.sim.needs)
        # The display loop is a thread of its own sleeping to absolute deadlines, not an executor
        # timer: behind input callbacks and executor overhead a timer tick came late often
        # enough to drop 7 % of the frames in the demo graph.
        self._stop_display = threading.Event()
        self.clock = DisplayClock()
        self._shown_head: np.ndarray | None = None      # the last head orientation that poked the display
        self._setup_gaze()                              # eye gaze (gaze_mode, raspv_spv.spv_node_gaze)
        self._setup_frames()                            # the phosphene frame in tf, the slam state in /spv/status
        self._setup_page()                              # the wearer's page's composited rate in the display budget
        self._display_thread = threading.Thread(target=self._display_loop, name="spv-display", daemon=True)
        self._headless_stamp: float | None = None
        if not self.params["headless"]:
            self._display_thread.start()
        self.create_timer(REPORT_PERIOD_S, self.report)
        # (joined in close: a daemon thread still inside rclpy's C++ at interpreter exit aborts the process)
        self._rate_check_thread = threading.Thread(target=self._check_rate_after_start, name="spv-rate-check",
                                                   daemon=True)
        self._rate_check_thread.start()
        self.publish_map()
        self.get_logger().info(self._describe(self.sim))

    def _update_subscriptions(self, needs: frozenset[str], reprojection: bool | None = None) -> None:
        """Subscribe to the inputs the mode and overlays read (needed or optional) and those the
        reprojection reads, and only those."""
        reprojection = self.view.reprojection if reprojection is None else reprojection
        mode_needs = frozenset(self.sim.mode.needs)
        watched = staleness.watched_inputs(mode_needs, [o.needs | o.optional_inputs for o in self.sim.overlays])
        self.staleness.watch(watched, staleness.expected_with(mode_needs), staleness.required_inputs(mode_needs))
        self.producers.watch({name: INPUT_TOPICS[name] for name in watched if name in INPUT_TOPICS})
        needs = (frozenset(needs) | self.sim.optional_inputs | watched
                 | (VIEW_INPUTS if reprojection else frozenset()))
        wanted = {"color": (Image, topics.COLOR, self.on_color), "depth": (Image, topics.DEPTH, self.on_depth),
                  "camera_pose": (PoseStamped, topics.CAMERA_POSE, self.on_pose),
                  "head": (QuaternionStamped, topics.HEAD_ORIENTATION, self.on_head),
                  "odom": (Odometry, topics.ODOM, self.on_odom),
                  "scene": (SceneStructureMsg, topics.SCENE_STRUCTURE, self.on_scene),
                  "scene_labels": (Image, topics.SCENE_LABELS, self.on_scene_labels),
                  "nav_path": (PathMsg, topics.NAV_PATH, self.on_nav_path),
                  "stairs": (StairDetection, topics.STAIRS, self.on_stairs),
                  "segmentation": (Image, topics.SEGMENTATION_LABELS, self.on_segmentation),
                  "segmentation_classes": (ClassNames, topics.SEGMENTATION_CLASSES, self.on_segmentation_classes),
                  "nav_guidance": (NavGuidance, topics.NAV_GUIDANCE, self.on_nav_guidance)}
        for name, (msg_type, topic, callback) in wanted.items():
            if name in needs and name not in self._subs:
                qos = (LATCHED_QOS if name == "segmentation_classes"
                       else LATEST_QOS if name in ("color", "depth", "scene", "scene_labels") else SENSOR_QOS)
                self._subs[name] = self.create_subscription(msg_type, topic, callback, qos)
            elif name not in needs and name in self._subs:
                self.destroy_subscription(self._subs.pop(name))
        unsupported = sorted(set(needs) - set(wanted) - {"camera"})
        if unsupported:
            self.warn_throttled("needs", f"mode {self.sim.config.mode} needs {', '.join(unsupported)}, which this node "
                                         "does not subscribe to; its phosphenes stay off")

    def _frame_arrived(self, which: str) -> None:
        """Recompute the levels when the mode's main input (colour, else depth) arrives; for
        scene modes, when the scene structure and labels of one depth frame are both in."""
        with self._sim_lock:
            sim = self.sim
        plan, sim, _ = self._shown_for(sim, time.monotonic())   # a fallback while inputs are stale
        if plan.no_data:
            return
        scene_inputs = sorted(staleness.SCENE_INPUTS & sim.needs)
        if scene_inputs:
            # scene modes run when the scene node's outputs of one depth frame are all in; with
            # carry_scene a newer depth frame is shown at once with them carried into it
            complete = which in scene_inputs and len({self.stamps[n] for n in scene_inputs}) == 1
            if complete and "scene_labels" in scene_inputs:     # by direction, for carrying into later frames
                self.view.remember_scene(self.stamps["scene_labels"], self.scene_labels)
            if (plan.normal and "scene_labels" in scene_inputs and (which == "depth" or complete)
                    and self._carry_scene(sim)):
                return
            if not complete:
                return
        elif which != ("color" if "color" in sim.needs else "depth"):
            return
        if self.intrinsics is None:
            now = time.monotonic()
            self._waiting_since = self._waiting_since or now
            if now - self._waiting_since > 1.0:          # not just the first frame overtaking the info
                self.warn_throttled("no-info", f"images arrive but no camera info on {topics.CAMERA_INFO}; "
                                               "phosphenes stay off until it comes")
            if self.params["headless"]:
                self._headless_tick(self.stamps[which])
            return
        stamp = self.stamps[which]

        def of_this_frame(name: str, value):          # scene outputs of another depth frame stay out
            return value if abs(self.stamps[name] - stamp) <= POSE_TOLERANCE_S else None
        inputs = FrameInputs(color=self.color, depth=self.depth, camera=self.intrinsics, stamp=stamp,
                             scene=of_this_frame("scene", self.scene),
                             scene_labels=of_this_frame("scene_labels", self.scene_labels),
                             scene_stamp=stamp if scene_inputs else 0.0, extras=dict(self.extras))
        if self._pending is not None:               # its pose never came: it goes with the pose there is
            if not self._pending_shown:
                self._finish_frame(self._pending)
            self._pending = None
        if "camera_pose" in sim.needs | sim.optional_inputs and self._pose_comes_later(inputs.stamp):
            # poses come, later than the images (RGB-D odometry): shown now with the pose
            # predicted at its stamp and recomputed when its own comes (on_pose), or waiting for it
            if self.params["predict_pose"] and not self.params["headless"]:
                pristine = dataclasses.replace(inputs, extras=dict(inputs.extras), cache={})
                self._finish_frame(inputs, predicted=True)
                self._pending, self._pending_shown = pristine, True
            else:
                self._pending, self._pending_shown = inputs, False
            return
        self._finish_frame(inputs)

    def _carry_scene(self, sim: PhospheneSimulator) -> bool:
        """Show the newest depth frame at once with the newest complete scene result carried
        into it by the camera's motion (:mod:`raspv_perception.scene_carry`; its own result
        replaces it when it comes). False when there is nothing to carry: ``carry_scene`` off,
        headless, no newer depth frame, or a result older than :data:`MAX_CARRY_S`."""
        if not self.params["carry_scene"] or self.params["headless"] or self.intrinsics is None:
            return False
        depth, labels, scene = self.depth, self.scene_labels, self.scene
        new, old = self.stamps["depth"], self.stamps["scene_labels"]
        if (depth is None or labels is None or not old < new - POSE_TOLERANCE_S or new - old > MAX_CARRY_S
                or depth.shape != (self.intrinsics.height, self.intrinsics.width)):
            return False
        if abs(self.stamps["scene"] - old) > POSE_TOLERANCE_S:
            if "scene" in sim.needs:
                return False                        # the structure of that frame is not in yet
            scene = None
        tracker = self.view.tracker
        at_new, at_old = tracker.camera_pose_predicted(new), tracker.camera_pose_predicted(old)
        new_from_old = np.eye(4) if at_new is None or at_old is None else np.linalg.inv(at_new) @ at_old
        if scene is not None:
            scene = structure_seen_from(scene, new_from_old)
        # what the newest result did not see from the views remembered in that direction (a head turned back)
        earlier = self.view.remembered_scenes(new, at_new, exclude=old)
        carried = carry_labels(labels, depth, self.intrinsics, new_from_old,
                               scene.floor_plane if scene is not None and scene.floor_found else None, earlier=earlier)
        inputs = FrameInputs(color=self.color, depth=depth, camera=self.intrinsics, stamp=new, scene=scene,
                             scene_labels=carried, scene_stamp=old, extras=dict(self.extras))
        self._finish_frame(inputs, predicted=self._pose_comes_later(new))
        return True

    def _pose_comes_later(self, stamp: float) -> bool:
        """Camera poses come, and the one of ``stamp`` [s] is not in yet (RGB-D odometry lags the images)."""
        newest_pose = self.view.tracker.newest_camera_pose_stamp()
        return newest_pose is not None and newest_pose < stamp - POSE_TOLERANCE_S

    def _finish_frame(self, inputs: FrameInputs, predicted: bool = False) -> None:
        """Levels of a complete frame, with the camera pose at its stamp (``predicted``: continued
        past the newest pose at its velocity), handed to the display."""
        self._pending = None
        with self._sim_lock:
            sim, map_id = self.sim, self.map_id
        plan, shown, _ = self._shown_for(sim, time.monotonic())
        if shown is not None:
            sim = shown
        tracker = self.view.tracker
        inputs.camera_pose = (tracker.camera_pose_predicted(inputs.stamp) if predicted
                              else tracker.camera_pose_at(inputs.stamp))
        if inputs.camera_pose is None:
            inputs.camera_pose = self.pose          # a source whose poses are not stamped like its images
        elif inputs.extras.get("stairs") and abs(self.stamps["stairs"] - inputs.stamp) > POSE_TOLERANCE_S:
            # the staircase was measured in an earlier depth frame: bring it into this frame's camera
            detected_at = self.view.tracker.camera_pose_at(self.stamps["stairs"])
            if detected_at is not None:
                here_from_there = np.linalg.inv(inputs.camera_pose) @ detected_at
                inputs.extras["stairs"] = [s.in_frame(here_from_there) for s in inputs.extras["stairs"]]
        try:
            levels = sim.levels(inputs)
        except InputError as exc:
            self.warn_throttled("input", f"cannot use this frame: {exc}")
            if self.params["headless"]:
                self._headless_tick(inputs.stamp)     # a frame still goes out: controllers wait for it
            return
        self.view.add_frame(DisplayFrame(inputs.stamp, inputs, levels, map_id, sim))
        if self.params["headless"]:
            self._headless_tick(inputs.stamp)
        else:
            self.clock.poke()

    def _headless_tick(self, stamp: float) -> None:
        """Publish the frame of input time ``stamp`` [s], the temporal model advancing by the
        display frames elapsed since the previous one."""
        last, self._headless_stamp = self._headless_stamp, stamp
        frames = 1 if last is None else max(1, int(round((stamp - last) * self.params["rate"])))
        self.tick(frames, stamp)

    # -- stale inputs -------------------------------------------------------------------------
    def _arrived(self, name: str) -> None:
        """A message of watched input ``name`` arrived (and, with RASPV_STARTUP_REPORT, when the first did)."""
        self.staleness.arrived(name, time.monotonic())
        self.producers.arrived(name)
        if name not in self._seen:
            self._seen.add(name)
            startup_mark(f"first {name}")

    def _shown_for(self, sim: PhospheneSimulator, now: float):
        """(plan, simulator to show it with, no-data pattern) for ``sim`` at monotonic ``now``
        (:mod:`raspv_spv.staleness`); cached while neither the simulator nor the stale inputs
        change, so a display tick costs one pass over the watched inputs."""
        with self._plan_lock:
            watching = self.params["stale_inputs"] and not self.params["headless"]
            producers = self.producers.states()        # (a new dict only when a producer's state changed)
            # with a simulated device latency the display shows the inputs that long later
            stale = self.staleness.check(now - self.view.latency_s, producers) if watching else frozenset()
            shown = self._shown
            if shown is not None and shown[0] is sim and shown[1] is stale:
                if self._status_args is None or producers is not self._status_args[2]:   # /spv/status tells the producers' states now
                    self._publish_status(shown[2], sim.config.mode, producers)
                return shown[2:]
            c = sim.config
            plan = staleness.plan_display(c.mode, frozenset(sim.mode.needs),
                                          [(n, o.needs | o.optional_inputs) for n, o in zip(c.overlays, sim.overlays)],
                                          stale)
            shown_sim = sim if plan.normal else None if plan.no_data else sim.variant(plan.mode, plan.overlays)
            pattern = shown[4] if shown is not None and shown[0] is sim else NoDataPattern.for_simulator(sim)
            previous = shown[2] if shown is not None else None
            self._shown = (sim, stale, plan, shown_sim, pattern)
        if previous is None or (plan.mode, plan.overlays) != (previous.mode, previous.overlays):
            self._report_plan(plan, c.mode, now, producers)
        return plan, shown_sim, pattern

    def _report_plan(self, plan: staleness.DisplayPlan, configured_mode: str, now: float,
                     producers: dict[str, str]) -> None:
        """Latched ``/spv/status`` (JSON) and a log line (at most one per 2 s) when what the display
        shows changes because inputs went stale or came back; ``producers``: the states the stale
        inputs were judged with (so the line and the episode counts agree)."""
        self._publish_status(plan, configured_mode, producers)
        if plan.normal:
            if self._stale_logged:
                self._stale_logged = False
                self.get_logger().info(f"inputs back: showing mode {configured_mode} again")
        elif all(self.staleness.never_arrived(n) for n in plan.stale):      # starting: not a fault
            self._stale_logged = True
            self.get_logger().info(f"waiting for {', '.join(sorted(plan.stale))}: showing "
                                   f"{plan.describe(configured_mode)} until it comes")
        elif now - self._plan_logged >= 2.0:
            self._plan_logged, self._stale_logged = now, True
            what = ", ".join(self.staleness.describe(n, now, producers.get(n, staleness.UNKNOWN))
                             for n in sorted(plan.stale))
            self.get_logger().warning(f"stale input: {what}; showing {plan.describe(configured_mode)} until it comes back")

    def _publish_status(self, plan: staleness.DisplayPlan, configured_mode: str, producers: dict[str, str]) -> None:
        """Latched ``/spv/status`` (JSON): what is shown, why, and the producers' states."""
        self._status_args = (plan, configured_mode, producers)
        status = {"showing": plan.mode, "overlays": list(plan.overlays), "mode": configured_mode,
                  "stale": sorted(plan.stale), "stale_episodes": self.staleness.episodes,
                  "late_episodes": self.staleness.late_episodes, "producers": dict(sorted(producers.items()))}
        display = self.display_status()                 # what the rate costs here, and whether the page keeps it
        if display is not None:
            status["display"] = display
        if getattr(self, "localisation", None) is not None:
            status["localisation"] = self.localisation
        try:
            self.pub_status.publish(String(data=json.dumps(status)))
        except RCLError:
            if self.context.ok():
                raise

    def close(self) -> None:
        self._close_gaze()
        self._builder.close()
        self._stop_display.set()
        self.clock.stop()
        for thread in (self._display_thread, self._rate_check_thread):
            if thread.is_alive():
                thread.join(timeout=2.0)
        # rclpy's context may already be shut down here: report with print, not the ROS logger
        if self._tick_ms:
            print(f"spv: {self._ticks} display frames, {self._dropped} dropped, "
                  f"tick median {statistics.median(self._tick_ms):.2f} ms; {self.view.turned_ticks} re-projected "
                  f"to a turned head ({self.view.filled_ticks} filled from remembered views); inputs went stale {self.staleness.episodes} times "
                  f"({self.staleness.late_episodes} of them late from a live node)", flush=True)


def main(argv=None) -> None:
    # The display thread must get the GIL promptly when its deadline comes: Python's default
    # 5 ms switch interval is a quarter of a 50 Hz frame.
    sys.setswitchinterval(0.0005)
    run_node(SpvNode, argv, priority="headset")


if __name__ == "__main__":
    main()
