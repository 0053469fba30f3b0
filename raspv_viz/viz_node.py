"""The `viz` node: what perception found as RViz/Foxglove markers, the depth as a point cloud.

Subscribes to /scene/structure, /stairs, /nav/path, /spv/map + /spv/frame, depth, colour and
camera info, and /camera/pose; publishes MarkerArrays on /viz/scene, /viz/stairs, /viz/path,
/viz/phosphenes and a PointCloud2 on /viz/cloud (raspv_common/topics.py). Markers of camera-frame
results are drawn in ``map`` with the camera pose at their stamp (``fixed_frame``), so the scene
stays put while the camera moves; RViz and Foxglove put ``map`` (and the camera's optical frame,
``fixed_frame: camera``) into any fixed frame of the graph's tf tree. Off the headset path: normal scheduling; depth,
colour and phosphene frames are taken raw and deserialised only at the cloud and phosphene rates.
"""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
from raspv_msgs.msg import PhospheneFrame, PhospheneMap, SceneStructure, StairDetection
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import CameraInfo, Image, PointCloud2
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from raspv_common import frames, topics
from raspv_common.conversions import (ImageEncodingError, depth_from_image, pose_to_matrix, rgb_from_image,
                                      stamp_to_seconds)
from raspv_common.node import RaspvNode, run_node
from raspv_common.pose_buffer import PoseBuffer
from raspv_common.qos import LATCHED_QOS, LATEST_QOS, SENSOR_QOS
from raspv_perception.scene_msg import structure_from_msg
from raspv_perception.stairs_msg import staircase_from_msg
from raspv_viz.cloud import decimated_points
from raspv_viz.phosphene_markers import phosphene_marker
from raspv_viz.scene_markers import path_markers, scene_markers, stair_markers
from raspv_viz.viz_msg import marker_array, point_cloud
from raspv_viz.viz_params import PARAMS

WORLD = frames.MAP


class VizNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("viz", PARAMS)
        self.poses = PoseBuffer(max_age_s=10.0, max_extrapolation_s=0.25)
        self.camera_frame = ""                 # frame_id of the depth images (the optical frame C)
        self.spv_map: PhospheneMap | None = None
        self._latest: dict[str, bytes] = {}    # raw depth, colour and phosphene frame, newest only
        self.pub_scene = self.create_publisher(MarkerArray, topics.VIZ_SCENE, SENSOR_QOS)
        self.pub_stairs = self.create_publisher(MarkerArray, topics.VIZ_STAIRS, SENSOR_QOS)
        self.pub_path = self.create_publisher(MarkerArray, topics.VIZ_PATH, SENSOR_QOS)
        self.pub_phosphenes = self.create_publisher(MarkerArray, topics.VIZ_PHOSPHENES, SENSOR_QOS)
        self.pub_cloud = self.create_publisher(PointCloud2, topics.VIZ_CLOUD, SENSOR_QOS)
        self.create_subscription(PoseStamped, topics.CAMERA_POSE, self.on_pose, SENSOR_QOS)
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self.on_camera_info, SENSOR_QOS)
        self.create_subscription(SceneStructure, topics.SCENE_STRUCTURE, self.on_scene, LATEST_QOS)
        self.create_subscription(StairDetection, topics.STAIRS, self.on_stairs, LATEST_QOS)
        self.create_subscription(PathMsg, topics.NAV_PATH, self.on_path, LATEST_QOS)
        self.create_subscription(PhospheneMap, topics.SPV_MAP, self.on_map, LATCHED_QOS)
        for name, topic, msg_type in (("depth", topics.DEPTH, Image), ("color", topics.COLOR, Image),
                                      ("frame", topics.SPV_FRAME, PhospheneFrame)):
            self.create_subscription(msg_type, topic, lambda raw, n=name: self._latest.__setitem__(n, raw),
                                     LATEST_QOS, raw=True)
        self._rate_timers = {}
        self._schedule("cloud", self.params["cloud_rate"], self.publish_cloud)
        self._schedule("phosphenes", self.params["phosphene_rate"], self.publish_phosphenes)

    # -- parameters -------------------------------------------------------------------------
    def on_parameters(self, changes):
        if "cloud_rate" in changes:
            self._schedule("cloud", changes["cloud_rate"], self.publish_cloud)
        if "phosphene_rate" in changes:
            self._schedule("phosphenes", changes["phosphene_rate"], self.publish_phosphenes)
        return None

    def _schedule(self, name: str, rate_hz: float, callback) -> None:
        old = self._rate_timers.pop(name, None)
        if old is not None:
            self.destroy_timer(old)
        if rate_hz > 0:
            self._rate_timers[name] = self.create_timer(1.0 / rate_hz, callback)

    # -- frames -----------------------------------------------------------------------------
    def on_pose(self, msg: PoseStamped) -> None:
        self.poses.add(stamp_to_seconds(msg.header.stamp), pose_to_matrix(msg.pose))

    def _use_world(self) -> bool:
        mode = self.params["fixed_frame"]
        return mode in ("map", "world") or (mode == "auto" and len(self.poses) > 0)

    def target_from_camera(self, header: Header) -> tuple[str, np.ndarray] | None:
        """(frame_id, · ← C) for camera-frame data stamped ``header``; None when the world frame
        is asked for and no pose is known at that stamp (warned about, throttled)."""
        if header.frame_id:
            self.camera_frame = header.frame_id
        if not self._use_world():
            return header.frame_id, np.eye(4)
        pose = self.poses.lookup_or_none(stamp_to_seconds(header.stamp))
        if pose is None:
            self.warn_throttled("pose", "no /camera/pose at the stamp of the data: markers skipped "
                                        "(set fixed_frame: camera for sources without a pose)")
            return None
        return WORLD, pose

    def target_from_world(self) -> tuple[str, np.ndarray] | None:
        """(frame_id, · ← W) for world-frame data (the path)."""
        if self._use_world():
            return WORLD, np.eye(4)
        latest = self.poses.latest()
        if latest is None or not self.camera_frame:
            return None
        return self.camera_frame, np.linalg.inv(latest.matrix)

    # -- inputs -----------------------------------------------------------------------------
    def on_scene(self, msg: SceneStructure) -> None:
        self._publish_from_camera(self.pub_scene, msg.header, lambda T: scene_markers(structure_from_msg(msg), T))

    def on_stairs(self, msg: StairDetection) -> None:
        self._publish_from_camera(self.pub_stairs, msg.header, lambda T: stair_markers(staircase_from_msg(msg), T))

    def _publish_from_camera(self, publisher, header: Header, shapes) -> None:
        """Markers ``shapes(T)`` of camera-frame data stamped ``header``, in the target frame."""
        target = self.target_from_camera(header)
        if target is not None:
            frame, T = target
            publisher.publish(marker_array(shapes(T), Header(stamp=header.stamp, frame_id=frame)))

    def on_path(self, msg: PathMsg) -> None:
        target = self.target_from_world()
        if target is not None:
            frame, T = target
            pts = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in msg.poses]).reshape(-1, 3)
            self.pub_path.publish(marker_array(path_markers(pts, T), Header(stamp=msg.header.stamp, frame_id=frame)))

    def on_map(self, msg: PhospheneMap) -> None:
        self.spv_map = msg

    # -- timers -----------------------------------------------------------------------------
    def publish_phosphenes(self) -> None:
        raw, m = self._latest.pop("frame", None), self.spv_map
        if raw is None or m is None:
            return
        frame = deserialize_message(raw, PhospheneFrame)
        if frame.map_id != m.map_id or len(frame.brightness) != len(m.display_x):
            return                                          # a frame of a map not received yet
        header = Header(stamp=frame.source_stamp, frame_id=self.camera_frame or frames.CAMERA_OPTICAL)
        target = self.target_from_camera(header)
        if target is None:
            return
        frame_id, T = target
        shapes = phosphene_marker(np.asarray(m.display_x), np.asarray(m.display_y), np.asarray(frame.brightness),
                                  np.asarray(m.dropped, dtype=bool), m.width, m.height, m.focal_px,
                                  m.phosphene_diameter_px, self.params["phosphene_distance"], T)
        self.pub_phosphenes.publish(marker_array(shapes, Header(stamp=frame.header.stamp, frame_id=frame_id)))

    def publish_cloud(self) -> None:
        raw = self._latest.pop("depth", None)
        if raw is None or self.intrinsics is None:
            return
        msg = deserialize_message(raw, Image)
        try:
            depth = depth_from_image(msg)
        except ImageEncodingError as exc:
            self.warn_throttled("depth", f"ignoring depth image: {exc}")
            return
        target = self.target_from_camera(msg.header)
        if target is None or depth.shape != (self.intrinsics.height, self.intrinsics.width):
            return
        frame, T = target
        rgb = self._color_at(msg.header.stamp) if self.params["cloud_color"] else None
        points, colors = decimated_points(depth, self.intrinsics, self.params["cloud_stride"],
                                          self.params["cloud_max_depth"], T, rgb)
        self.pub_cloud.publish(point_cloud(points, colors, Header(stamp=msg.header.stamp, frame_id=frame)))

    def _color_at(self, stamp) -> np.ndarray | None:
        """The newest colour image if it has the depth's stamp (sources publish both per frame)."""
        raw = self._latest.get("color")
        if raw is None:
            return None
        color = deserialize_message(raw, Image)
        if color.header.stamp != stamp:
            return None
        try:
            return rgb_from_image(color)
        except ImageEncodingError:
            return None


def main(argv=None) -> None:
    run_node(VizNode, argv, priority="perception")


if __name__ == "__main__":
    main()
