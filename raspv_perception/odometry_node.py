"""`odometry` node: RGB-D odometry → /camera/pose (W ← camera optical) for sources without a pose.

Colour and depth are paired by stamp and registered frame to frame (``rgbd_odometry``), at
most ``max_rate`` frames per second by their stamps (the phosphenes do not wait for the poses:
the spv node predicts them). The
world frame W is the first camera frame made gravity-aligned by the first floor the `scene`
node reports (z up, z = 0 on the floor, x along the first view direction); poses are published
from then on. Without a floor within ``anchor_timeout`` seconds (or with
``gravity_from_floor`` off) the first camera is assumed level and W sits at its centre.
A failed registration holds the last pose and is reported (throttled).

``/camera/pose`` is in ``map``; tf: ``map → odom`` identity on /tf_static (this odometry does not
correct its drift: map = odom) and ``odom → base_link`` per pose (through the source's mounting,
:class:`~raspv_common.tf_messages.CameraPoseTf`). The `slam` node is the peer that corrects it.
"""
from __future__ import annotations

import time
from collections import OrderedDict

import numpy as np
from geometry_msgs.msg import PoseStamped
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from sensor_msgs.msg import CameraInfo, Image

from raspv_common import frames, topics
from raspv_common.conversions import (ImageEncodingError, depth_from_image, matrix_to_pose,
                                      rgb_from_image)
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import LATEST_QOS, SENSOR_QOS
from raspv_common.tf_messages import CameraPoseTf
from raspv_perception.odometry_params import PARAMS
from raspv_perception.rgbd_odometry import OdometryConfig, RGBDOdometry


FRAME_SLACK_NS = 5_000_000      # stamps jitter: a frame this much early still counts as due [ns]


class OdometryNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("odometry", PARAMS)
        p = self.params
        try:
            self.odometry = RGBDOdometry(OdometryConfig(scale=p["scale"], max_depth=p["max_depth"],
                                                        min_overlap=p["min_overlap"], threads=p["threads"]))
        except ValueError as exc:
            raise ConfigurationError(str(exc)) from None
        self.pending: OrderedDict[int, dict] = OrderedDict()     # stamp [ns] → {"color": msg, "depth": msg}
        self.history: OrderedDict[int, np.ndarray] = OrderedDict()  # stamp [ns] → C0 ← C
        self.started: float | None = None
        self.last_key: int | None = None            # stamp [ns] of the last frame registered
        self.publishing = not p["gravity_from_floor"]
        self.pub_pose = self.create_publisher(PoseStamped, topics.CAMERA_POSE, SENSOR_QOS)
        self.tf = CameraPoseTf(self, static_map_odom=True)
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self.on_camera_info, SENSOR_QOS)
        self.create_subscription(Image, topics.COLOR, lambda m: self.on_image("color", m), LATEST_QOS)
        self.create_subscription(Image, topics.DEPTH, lambda m: self.on_image("depth", m), LATEST_QOS)
        if p["gravity_from_floor"]:
            self.create_subscription(SceneStructureMsg, topics.SCENE_STRUCTURE, self.on_scene, SENSOR_QOS)


    @staticmethod
    def _key(msg) -> int:
        return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec

    def on_image(self, kind: str, msg: Image) -> None:
        key = self._key(msg)
        entry = self.pending.setdefault(key, {})
        entry[kind] = msg
        while len(self.pending) > 6:
            self.pending.popitem(last=False)
        if "color" in entry and "depth" in entry:
            # older unmatched frames will never be completed
            for k in [k for k in self.pending if k <= key]:
                del self.pending[k]
            self.process(key, entry["color"], entry["depth"])

    def process(self, key: int, color_msg: Image, depth_msg: Image) -> None:
        if self.intrinsics is None:
            self.warn_throttled("no-info", f"waiting for {topics.CAMERA_INFO}")
            return
        rate = self.params["max_rate"]
        if rate > 0 and self.last_key is not None and 0 <= key - self.last_key < 1e9 / rate - FRAME_SLACK_NS:
            return                                   # too soon after the last registered frame
        self.last_key = key
        try:
            rgb = rgb_from_image(color_msg)
            depth = depth_from_image(depth_msg)
            step = self.odometry.process(np.ascontiguousarray(rgb), depth, self.intrinsics)
        except (ImageEncodingError, ValueError) as exc:
            self.warn_throttled("input", f"ignoring frame: {exc}")
            return
        if self.started is None:
            self.started = time.monotonic()
        if not step.tracked:
            self.warn_throttled("lost", f"registration failed (matched {self.odometry.last_overlap:.0%} of the pixels); "
                                        "holding the last pose")
        self.history[key] = self.odometry.c0_from_camera.copy()
        while len(self.history) > 100:
            self.history.popitem(last=False)
        if not self.publishing and time.monotonic() - self.started > self.params["anchor_timeout"]:
            self.get_logger().warning(f"no floor from {topics.SCENE_STRUCTURE} within {self.params['anchor_timeout']} s: "
                                      "assuming the first camera frame was level")
            self.publishing = True
        if self.publishing:
            out = PoseStamped(header=depth_msg.header)
            out.header.frame_id = frames.MAP
            out.pose = matrix_to_pose(step.world_from_camera)
            self.pub_pose.publish(out)
            self.tf.publish(depth_msg.header.stamp, depth_msg.header.frame_id, step.world_from_camera)

    def on_scene(self, msg: SceneStructureMsg) -> None:
        if self.odometry.anchored or self.publishing or not msg.floor_found:   # never move a published world
            return
        c0_from_camera = self.history.get(self._key(msg))
        if c0_from_camera is None:
            return
        try:
            self.odometry.anchor_to_floor(np.array(msg.floor_plane, dtype=np.float64), c0_from_camera)
        except ValueError as exc:
            self.warn_throttled("anchor", f"ignoring floor: {exc}")
            return
        self.publishing = True
        self.get_logger().info(f"world frame anchored to the floor ({msg.camera_height:.2f} m below the camera)")


def main(argv=None) -> None:
    run_node(OdometryNode, argv, priority="perception")


if __name__ == "__main__":
    main()
