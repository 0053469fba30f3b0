"""`slam` node: RGB-D SLAM (:class:`raspv_slam.slam_system.SlamSystem`) as the graph's pose source.

Takes what the `odometry` node takes (colour, depth, camera info; the floor from
``/scene/structure``) and publishes what it publishes — ``/camera/pose`` (map ← camera optical,
frame ``map``) — so perception, the planner and the spv node use either unchanged. Besides:

- tf: ``map → odom`` (the correction: moves at loop closures and relocalisations) and
  ``odom → base_link`` (continuous) per frame, through the source's mounting
  (:class:`~raspv_common.tf_messages.CameraPoseTf`);
- ``/slam/state`` (std_msgs/String JSON, transient-local), per processed frame: its stamp, the
  tracking state (initialising, tracking, lost, relocalised, loop_closed, new_map, map_merged),
  ``map_id`` (the sub-map the pose is in: 0 the first map; another after a new map was started
  while lost in an unmapped place, until it is merged back), reference keyframe,
  inliers, time, frames processed and dropped; the spv node puts the state into ``/spv/status``;
- ``/slam/markers`` (MarkerArray, map frame): keyframes, trajectory, landmarks, loop edges
  (:mod:`raspv_viz.slam_markers`), while someone subscribes;
- ``/slam/save_map`` (raspv_msgs/srv/SaveMap): save now. Mapping saves at exit
  (``save_on_exit``) and every ``autosave_period`` s (:func:`raspv_slam.map_store.save_map`
  writes a new folder and renames it over the old one, so a node killed mid-save leaves the
  previous map whole).

Processing never blocks the executor: the callbacks keep only the newest colour/depth pair
(LATEST_QOS) and a worker thread takes it, so a slow frame drops the frames that came meanwhile
instead of queueing them. A new map is made gravity-aligned by the first floor the scene node
reports (as the odometry node does); poses are published from then on (or after
``anchor_timeout`` without a floor, in the first camera's axes until a floor aligns the map: one
jump). While tracking is lost (relocalising) the pose is carried by the core's continuous
odometry (map ← odom · odom ← camera), so the graph keeps its mode as with the odometry node's
held pose; ``/slam/state`` and ``/spv/status`` say it is lost.
"""
from __future__ import annotations

import datetime as _dt
import json
import threading
import time
from collections import deque
from pathlib import Path

import numpy as np
import open3d  # noqa: F401  -- the core's dense registration imports it at its first frame: 3-13 s of frames lost
from geometry_msgs.msg import PoseStamped
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from raspv_msgs.srv import SaveMap
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header, String
from visualization_msgs.msg import MarkerArray

from raspv_common import frames, topics
from raspv_common.conversions import (ImageEncodingError, camera_info_distortion, depth_from_image, matrix_to_pose,
                                      rgb_from_image)
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.pose_buffer import PoseBuffer
from raspv_common.qos import LATCHED_QOS, LATEST_QOS, SENSOR_QOS
from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown
from raspv_common.tf_messages import CameraPoseTf
from raspv_slam.config import SlamConfig
from raspv_slam.flow_tracking import FlowTracker
from raspv_slam.map_store import SlamMapError, maps_dir, resolve_map_path
from raspv_slam.results import TrackingState
from raspv_slam.slam_params import PARAMS
from raspv_slam.slam_system import SlamSystem          # (OpenCV, Open3D, GTSAM) before the subscriptions exist
from raspv_viz.slam_markers import slam_markers
from raspv_viz.viz_msg import marker_array

# saving on request or at exit waits this long [s] for the loop closer's backlog (minutes on a long
# walk through new places); the keyframes it did not process are saved as tracking placed them
EXIT_LOOP_WAIT_S = 10.0
FRAME_SLACK_NS = 5_000_000      # stamps jitter: a frame this much early still counts as due (max_rate) [ns]


def _key(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


class SlamNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("slam", PARAMS)
        p = self.params
        if p["mode"] == "localisation" and not p["map"]:
            raise ConfigurationError("mode 'localisation' needs a saved map: set 'map' to its name or path")
        self.map_path = resolve_map_path(p["map"]) if p["map"] else None
        self.save_path: Path | None = None             # where mapping saves (localisation: never)
        if p["mode"] == "mapping":
            self.save_path = (resolve_map_path(p["save_to"]) if p["save_to"] else self.map_path
                              or maps_dir() / _dt.datetime.now().strftime("slam-%Y%m%d-%H%M%S"))
        self.system = None                      # made at the first camera info (the core needs the intrinsics)
        self.distortion: tuple[float, ...] = ()  # the camera info's lens distortion (OpenCV coefficients)
        self.pub_pose = self.create_publisher(PoseStamped, topics.CAMERA_POSE, SENSOR_QOS)
        self.pub_state = self.create_publisher(String, topics.SLAM_STATE, LATCHED_QOS)
        self.pub_markers = self.create_publisher(MarkerArray, topics.SLAM_MARKERS, SENSOR_QOS)
        self.tf = CameraPoseTf(self, static_map_odom=False)
        self._pending: dict[int, dict] = {}      # stamp [ns] → {"color": msg, "depth": msg}
        self._newest: tuple[int, Image, Image] | None = None
        self._floors: deque[tuple[float, np.ndarray]] = deque(maxlen=20)   # (stamp, plane) to anchor to
        self._wake = threading.Condition()
        self._stop = False
        self._lock = threading.Lock()            # the SLAM system: the worker, saving and the service
        self._autosaving = threading.Lock()
        self._saving = threading.Lock()          # one save at a time (never the tracking lock: a large map takes seconds)
        self._closing = False
        self.anchored = not p["gravity_from_floor"]
        self.publishing = self.anchored
        self.first_frame_s: float | None = None
        self.counts = {"frames": 0, "dropped": 0, "flow_frames": 0}
        self.flow: FlowTracker | None = None    # poses of the frames between max_rate's (worker thread only)
        self._flow_ref: tuple[np.ndarray, np.ndarray] | None = None   # (odom ← C, map ← odom) of its reference
        self._odom_poses = PoseBuffer(max_age_s=2.0, max_extrapolation_s=0.2)   # odom ← C published (a guess)
        self._last_state: str | None = None
        self._last_map_id = 0
        self._markers_sent = 0.0
        self._last_key: int | None = None
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self.on_camera_info, SENSOR_QOS)
        self.create_subscription(Image, topics.COLOR, lambda m: self.on_image("color", m), LATEST_QOS)
        self.create_subscription(Image, topics.DEPTH, lambda m: self.on_image("depth", m), LATEST_QOS)
        if p["gravity_from_floor"]:
            self.create_subscription(SceneStructureMsg, topics.SCENE_STRUCTURE, self.on_scene, SENSOR_QOS)
        self.create_service(SaveMap, topics.SLAM_SAVE_MAP, self.on_save_map)
        if self.save_path is not None and p["autosave_period"] > 0:
            self._autosave = self.create_timer(p["autosave_period"], self.autosave)
        self._worker = threading.Thread(target=self._work, name="slam", daemon=True)
        self._worker.start()
        self.get_logger().info(f"{p['mode']}" + (f" in map {self.map_path}" if self.map_path else " a new map")
                               + (f"; saving to {self.save_path}" if self.save_path else ""))

    # -- inputs (executor thread: store the newest, never process here) ------------------------
    def on_image(self, kind: str, msg: Image) -> None:
        key = _key(msg)
        entry = self._pending.setdefault(key, {})
        entry[kind] = msg
        if "color" in entry and "depth" in entry:
            for k in [k for k in self._pending if k <= key]:
                del self._pending[k]                     # older unmatched halves will never be completed
            with self._wake:
                if self._newest is not None:
                    self.counts["dropped"] += 1          # the worker was busy: this one replaces it
                self._newest = (key, entry["color"], entry["depth"])
                self._wake.notify()
        while len(self._pending) > 6:
            self._pending.pop(min(self._pending))

    def on_camera_info(self, msg: CameraInfo) -> None:
        """Keep the intrinsics and the lens distortion: the core undistorts the keypoints (a raw
        Kinect-class image unrectified is off by degrees at its edges, which PnP and the dense
        registration take for rotation). The distortion is kept before the intrinsics: the worker
        makes the core as soon as it sees intrinsics (it took the first ones without distortion
        when it ran in between, one run in a few)."""
        try:
            self.distortion = camera_info_distortion(msg)
        except ValueError as exc:
            self.distortion = ()
            self.warn_throttled("distortion", f"camera info: {exc}; tracking as if the images were rectified")
        super().on_camera_info(msg)

    def on_scene(self, msg: SceneStructureMsg) -> None:
        if self.anchored or not msg.floor_found:
            return
        with self._wake:
            self._floors.append((_key(msg) * 1e-9, np.array(msg.floor_plane, dtype=np.float64)))

    # -- the worker thread -----------------------------------------------------------------------
    def _work(self) -> None:
        while True:
            with self._wake:
                while self._newest is None and not self._stop:
                    self._wake.wait()
                if self._stop:
                    return
                (key, color_msg, depth_msg), self._newest = self._newest, None
            rate = self.params["max_rate"]
            due = not (rate > 0 and self._last_key is not None and 0 <= key - self._last_key < 1e9 / rate - FRAME_SLACK_NS)
            try:
                if not due:
                    self._flow_frame(key, color_msg)
                    continue
                processed = self._process(key, color_msg, depth_msg)
            except SHUTDOWN_ERRORS as exc:           # Ctrl-C/SIGTERM ended the context while it published
                if during_shutdown(exc, self.context):
                    return
                raise
            if processed:
                self._last_key = key

    def _ensure_system(self) -> bool:
        if self.system is not None:
            return True
        if self.intrinsics is None:
            self.warn_throttled("no-info", f"waiting for {topics.CAMERA_INFO}")
            return False
        # the camera's lens distortion is the live camera's: a loaded map's keypoints are stored undistorted
        # so is its rolling shutter (a map's keyframes are stored corrected to mid-row time)
        run_settings = {"threads": self.params["threads"], "new_map_after": self.params["new_map_after"],
                        "distortion": self.distortion,
                        "rolling_shutter_readout": float(self.params["rolling_shutter_readout"])}
        try:
            if self.map_path is not None:               # the map's settings, this node's run settings
                localising = self.params["mode"] == "localisation"
                self.system = SlamSystem.load(self.map_path, self.intrinsics, localisation_only=localising,
                                              run_settings=run_settings)
                self.anchored = self.publishing = True          # a saved map has its frame already
            else:
                self.system = SlamSystem(self.intrinsics, SlamConfig(**run_settings))
            if self.params["flow_between"]:
                self.flow = FlowTracker(self.intrinsics, self.distortion)
        except (OSError, ValueError) as exc:          # SlamMapError is a ValueError: one line naming the map
            self.get_logger().fatal(f"cannot use map {self.map_path}: {exc}")
            self.exit_code = 2
            self.context.try_shutdown()
            return False
        return True

    def _anchor_to_a_floor(self, newest: float) -> None:
        """Anchor a new map to the first floor seen in a frame the system tracked. The scene node
        and this one each take the newest frame, so a floor may belong to a frame this node skipped:
        it waits (while its frame may still come) and is then dropped."""
        with self._wake:
            floors = list(self._floors)
        for stamp, plane in floors:
            try:
                self.system.anchor_to_floor(plane, stamp)
            except ValueError:
                if stamp < newest:                        # its frame was skipped: it never will be tracked
                    with self._wake:
                        if (stamp, plane) in self._floors:
                            self._floors.remove((stamp, plane))
                continue
            self.anchored = self.publishing = True
            self.get_logger().info("map frame anchored to the floor (z up, z = 0 on the floor)")
            return

    def _process(self, key: int, color_msg: Image, depth_msg: Image) -> bool:
        """Track one frame and publish; False when it could not be processed."""
        with self._lock:
            if not self._ensure_system():
                return False
            try:
                rgb = np.ascontiguousarray(rgb_from_image(color_msg))
                depth = self.read_depth(depth_msg)
            except ImageEncodingError as exc:
                self.warn_throttled("input", f"ignoring frame: {exc}")
                return False
            stamp = key * 1e-9
            result = self.system.process(stamp, rgb, depth)
            if not self.anchored and self._floors:
                self._anchor_to_a_floor(stamp)
        self.counts["frames"] += 1
        now = time.monotonic()
        if self.first_frame_s is None:
            self.first_frame_s = now
        if not self.publishing and now - self.first_frame_s > self.params["anchor_timeout"]:
            self.get_logger().warning(f"no floor from {topics.SCENE_STRUCTURE} within {self.params['anchor_timeout']} s: "
                                      "the map keeps the first camera's axes (assumed level) until one comes")
            self.publishing = True
        if self.publishing:
            self._publish(result, depth_msg.header)
        self._publish_state(result)
        self._publish_markers(now)
        self._flow_ref = None
        if self.flow is not None and result.map_from_camera is not None:
            if self.flow.set_reference(stamp, rgb, depth) >= self.flow.config.min_inliers:
                self._flow_ref = (result.odom_from_camera, result.map_from_odom)
        return True

    def _flow_frame(self, key: int, color_msg: Image) -> None:
        """A frame ``max_rate`` leaves out: posed from the last tracked frame by optical flow (when
        that frame was tracked and the flow finds it), published like the core's poses."""
        if self._flow_ref is None or not self.publishing:
            return
        try:
            rgb = np.ascontiguousarray(rgb_from_image(color_msg))
        except ImageEncodingError as exc:
            self.warn_throttled("input", f"ignoring frame: {exc}")
            return
        ref_odom, map_from_odom = self._flow_ref
        guess = self._odom_poses.predict(key * 1e-9, 0.2)
        flow = self.flow.track(rgb, None if guess is None else np.linalg.inv(ref_odom) @ guess)
        if flow.ref_from_camera is None:
            return
        self.counts["flow_frames"] += 1
        odom_from_camera = ref_odom @ flow.ref_from_camera
        self._send(color_msg.header, odom_from_camera, map_from_odom, map_from_odom @ odom_from_camera)

    # -- outputs -------------------------------------------------------------------------------
    def _publish(self, result, header) -> None:
        pose = result.map_from_camera
        if pose is None and result.state != TrackingState.INITIALISING:
            pose = result.map_from_odom @ result.odom_from_camera        # lost: carried by the motion model
        self._send(header, result.odom_from_camera, result.map_from_odom, pose)

    def _send(self, header, odom_from_camera: np.ndarray, map_from_odom: np.ndarray, pose: np.ndarray | None) -> None:
        """tf (map → odom → base_link) and /camera/pose (map ← C) of one frame."""
        self.tf.publish(header.stamp, header.frame_id, odom_from_camera, map_from_odom)
        self._odom_poses.add(header.stamp.sec + header.stamp.nanosec * 1e-9, odom_from_camera)
        if pose is not None:
            out = PoseStamped(header=Header(stamp=header.stamp, frame_id=frames.MAP))
            out.pose = matrix_to_pose(pose)
            self.pub_pose.publish(out)

    def _publish_state(self, result) -> None:
        state = result.state.value
        if state != self._last_state and self._last_state is not None:
            self.get_logger().info(f"tracking state: {self._last_state} → {state}")
        self._last_state = state
        if result.map_id != self._last_map_id:
            self.get_logger().info(f"map {self._last_map_id} → {result.map_id} ({state}): "
                                   + ("poses are in a new map's frame until it is merged"
                                      if result.state.value == "new_map" else "poses are in that map's frame"))
            self._last_map_id = result.map_id
        doc = {"state": state, "map_id": result.map_id, "stamp": result.stamp, "keyframe": result.keyframe_id, "inliers": result.inliers,
               "time_ms": round(result.time_ms, 1), "mode": self.params["mode"], "anchored": self.anchored,
               "frames": self.counts["frames"], "dropped": self.counts["dropped"],
               "flow_frames": self.counts["flow_frames"],
               "map": str(self.map_path) if self.map_path else ""}
        self.pub_state.publish(String(data=json.dumps(doc)))

    def _publish_markers(self, now: float) -> None:
        period = self.params["marker_period"]
        if period <= 0 or now - self._markers_sent < period or self.pub_markers.get_subscription_count() == 0:
            return
        self._markers_sent = now
        with self._lock:
            snap = self.system.snapshot(occupancy=False)     # the markers do not draw it; it takes seconds on a large map
        shapes = slam_markers(snap.keyframe_poses, snap.landmarks, snap.loop_edges,
                              getattr(snap, "covisibility_edges", []))
        self.pub_markers.publish(marker_array(shapes, Header(stamp=self.get_clock().now().to_msg(),
                                                             frame_id=frames.MAP)))

    # -- saving ----------------------------------------------------------------------------------
    def save(self, path: Path | None = None, wait_for_loops_s: float | None = EXIT_LOOP_WAIT_S) -> tuple[bool, str, str, int]:
        """(success, message, path, keyframes) of saving the map now (to ``path`` or ``save_path``),
        the loop closer's backlog waited for at most ``wait_for_loops_s``. Tracking goes on
        meanwhile: the core copies the map under the map's own lock and writes outside it."""
        target = path or self.save_path
        if target is None:
            return False, "localisation mode does not change the map: nothing to save", "", 0
        t0 = time.monotonic()
        with self._lock:
            system = self.system
        if system is None:
            return False, "no map yet (no frame processed)", "", 0
        with self._saving:
            try:
                system.save(target, wait_for_loops_s=wait_for_loops_s)
            except (OSError, SlamMapError) as exc:
                return False, f"could not save the map to {target}: {exc}", str(target), 0
            keyframes = len(system.map.keyframes)
        return True, f"map saved to {target} ({keyframes} keyframes, {time.monotonic() - t0:.2f} s)", str(target), \
            keyframes

    def on_save_map(self, request: SaveMap.Request, response: SaveMap.Response) -> SaveMap.Response:
        ok, message, path, keyframes = self.save(resolve_map_path(request.path) if request.path else None)
        response.success, response.message, response.path, response.keyframes = ok, message, path, keyframes
        if ok:
            self.get_logger().info(message)
        else:
            self.get_logger().warning(message)
        return response

    def autosave(self) -> None:
        """Save in a thread of its own (the executor keeps serving); one at a time."""
        if self.system is not None and not self._closing and self._autosaving.acquire(blocking=False):
            threading.Thread(target=self._autosave_now, name="slam-autosave", daemon=True).start()

    def _autosave_now(self) -> None:
        try:
            ok, message, _, _ = self.save(wait_for_loops_s=0.0)      # what the map holds now
            if not ok:
                self.warn_throttled("autosave", message, period_s=60.0)
        finally:
            self._autosaving.release()

    def close(self) -> None:
        self._closing = True
        with self._wake:
            self._stop = True
            self._wake.notify()
        self._worker.join(timeout=10.0)
        if self.system is None:
            return
        if self.save_path is not None and self.params["save_on_exit"]:
            ok, message, _, _ = self.save()
            print(f"slam: {message}", flush=True)
        self.system.close()
        self.system = None


def main(argv=None) -> None:
    run_node(SlamNode, argv, priority="perception")


if __name__ == "__main__":
    main()
