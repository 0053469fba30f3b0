"""`synthetic` node: publishes the analytic room of :mod:`raspv_camera.synthetic_scene` on the
standard source topics (colour, depth, camera info, camera pose in ``map``) and its ground truth as
tf (``map → odom`` identity, ``odom → base_link`` moving, the camera as the body:
``base_link → camera_link → frame_id``)."""
from __future__ import annotations

import time

from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header

from raspv_camera.synthetic_params import PARAMS
from raspv_camera.synthetic_scene import SyntheticRoom
import numpy as np

from raspv_common import frames, topics
from raspv_common.conversions import array_to_image, intrinsics_to_camera_info, matrix_to_pose
from raspv_common.intrinsics import CameraIntrinsics
from raspv_common.node import RaspvNode, run_node
from raspv_common.qos import SENSOR_QOS
from raspv_common.tf_messages import StaticTfBroadcaster, TfBroadcaster


class SyntheticSourceNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("synthetic", PARAMS)
        p = self.params
        self.intrinsics = CameraIntrinsics.from_hfov(p["width"], p["height"], p["hfov_deg"])
        self.room = SyntheticRoom(self.intrinsics, eye_height=p["eye_height"], pitch_down_deg=p["pitch_down_deg"],
                                  walk_speed=p["walk_speed"])
        self.pub_color = self.create_publisher(Image, topics.COLOR, SENSOR_QOS)
        self.pub_depth = self.create_publisher(Image, topics.DEPTH, SENSOR_QOS)
        self.pub_info = self.create_publisher(CameraInfo, topics.CAMERA_INFO, SENSOR_QOS)
        self.pub_pose = self.create_publisher(PoseStamped, topics.CAMERA_POSE, SENSOR_QOS)
        self.tf = TfBroadcaster(self)
        StaticTfBroadcaster(self).send([(frames.MAP, frames.ODOM, np.eye(4)),
                                        *frames.camera_mounting_edges(p["frame_id"])])
        self.base_from_camera = np.linalg.inv(frames.LINK_FROM_OPTICAL)
        self.t0 = time.monotonic()
        self.create_timer(1.0 / p["rate"], self.tick)
        self.get_logger().info(f"synthetic room at {p['width']}x{p['height']}, {p['rate']:.0f} Hz")

    def on_parameters(self, changes):
        for key in ("eye_height", "pitch_down_deg", "walk_speed"):
            if key in changes:
                setattr(self.room, key, changes[key])
        return None

    def tick(self) -> None:
        pose = self.room.pose_at(time.monotonic() - self.t0)
        color, depth = self.room.render(pose)
        header = self.header(self.params["frame_id"])
        self.pub_color.publish(array_to_image(color, "rgb8", header))
        self.pub_depth.publish(array_to_image(depth, "32FC1", header))
        self.pub_info.publish(intrinsics_to_camera_info(self.intrinsics, header))
        self.tf.send([(frames.ODOM, frames.BASE_LINK, pose @ self.base_from_camera)], header.stamp)
        self.pub_pose.publish(PoseStamped(header=Header(stamp=header.stamp, frame_id=frames.MAP), pose=matrix_to_pose(pose)))


def main(argv=None) -> None:
    run_node(SyntheticSourceNode, argv, priority="source")


if __name__ == "__main__":
    main()
