"""`stairs` node: depth + camera info + /scene/structure (for the floor) → /stairs.

The scene node stamps its structure with the depth image's header, so each structure is paired
with the depth image of the same stamp (kept for a few frames); the detection carries that
header too. Without a floor the node publishes ``detected = false``.
"""
from __future__ import annotations

import dataclasses
from collections import OrderedDict

import numpy as np
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from raspv_msgs.msg import StairDetection
from sensor_msgs.msg import CameraInfo, Image

from raspv_common import topics
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import SENSOR_QOS
from raspv_perception.scene_msg import structure_from_msg
from raspv_perception.stairs import StairConfig, StairDetector
from raspv_perception.stairs_msg import staircase_to_msg
from raspv_perception.stairs_params import CONFIG_FIELDS, PARAMS

KEEP_DEPTH_FRAMES = 10


def config_from_params(p: dict) -> StairConfig:
    """StairConfig from node parameters (ValueError with the reason if inconsistent)."""
    return dataclasses.replace(StairConfig(), **{k: p[k] for k in CONFIG_FIELDS})


class StairsNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("stairs", PARAMS)
        try:
            self.detector = StairDetector(config_from_params(self.params))
        except ValueError as exc:
            raise ConfigurationError(str(exc)) from None
        self.depths: OrderedDict[tuple[int, int], np.ndarray] = OrderedDict()
        self.detections = 0
        self.pub = self.create_publisher(StairDetection, topics.STAIRS, SENSOR_QOS)
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self.on_camera_info, SENSOR_QOS)
        self.create_subscription(Image, topics.DEPTH, self.on_depth, SENSOR_QOS)
        self.create_subscription(SceneStructureMsg, topics.SCENE_STRUCTURE, self.on_structure, SENSOR_QOS)

    def on_parameters(self, changes):
        try:
            config = config_from_params({**self.params, **changes})
        except ValueError as exc:
            return str(exc)
        self.detector = StairDetector(config)
        return None

    def on_depth(self, msg: Image) -> None:
        depth = self.read_depth(msg)
        if depth is None:
            return
        self.depths[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = depth
        while len(self.depths) > KEEP_DEPTH_FRAMES:
            self.depths.popitem(last=False)

    def on_structure(self, msg: SceneStructureMsg) -> None:
        if self.intrinsics is None:
            self.warn_throttled("no-info", f"waiting for {topics.CAMERA_INFO}")
            return
        depth = self.depths.pop((msg.header.stamp.sec, msg.header.stamp.nanosec), None)
        if depth is None:
            self.warn_throttled("no-depth", f"no {topics.DEPTH} image with the stamp of a {topics.SCENE_STRUCTURE} "
                                            "message (is the scene node fed by the same source?)")
            return
        stair = self.detector.detect(depth, self.intrinsics, structure_from_msg(msg))
        self.pub.publish(staircase_to_msg(stair, msg.header))
        if stair is not None:
            self.detections += 1
            if self.detections == 1:
                self.get_logger().info(f"first staircase: {stair.direction.name.lower()}, {len(stair.steps)} steps, "
                                       f"riser {stair.riser:.3f} m, tread {stair.tread:.3f} m, width {stair.width:.2f} m, "
                                       f"{stair.distance:.1f} m away")


def main(argv=None) -> None:
    run_node(StairsNode, argv, priority="perception")


if __name__ == "__main__":
    main()
