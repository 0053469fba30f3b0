"""The RASPV graph's topics with their message types and durability, known before discovery (no ROS).

`raspv bag record` subscribes to these at start — before the DDS graph discovery has even seen
a publisher — so the first message a node publishes is in the bag (a subscription made after
discovery misses what was published meanwhile: 2.4–2.8 s of a demo, issue 16). Topics not in
this table (a user's own) are still picked up by discovery. Every topic of
:mod:`raspv_common.topics` must be here (a test checks the table against it).
"""
from __future__ import annotations

from raspv_common import topics as T

# name → (message type, latched: published transient-local)
KNOWN_TOPICS: dict[str, tuple[str, bool]] = {
    T.COLOR: ("sensor_msgs/msg/Image", False),
    T.DEPTH: ("sensor_msgs/msg/Image", False),
    T.CAMERA_INFO: ("sensor_msgs/msg/CameraInfo", False),
    T.CAMERA_POSE: ("geometry_msgs/msg/PoseStamped", False),
    T.DEPTH_INFO: ("sensor_msgs/msg/CameraInfo", False),
    T.IMU: ("sensor_msgs/msg/Imu", False),
    T.ODOM: ("nav_msgs/msg/Odometry", False),
    T.SIM_LABELS: ("sensor_msgs/msg/Image", False),
    T.SIM_COLLISIONS: ("raspv_msgs/msg/CollisionEvent", False),
    T.SIM_CLASSES: ("std_msgs/msg/String", True),
    T.SIM_LOCKSTEP: ("geometry_msgs/msg/TwistStamped", False),
    T.CMD_VEL: ("geometry_msgs/msg/Twist", False),
    T.HEAD_ORIENTATION: ("geometry_msgs/msg/QuaternionStamped", False),
    T.GAZE_DIRECTION: ("geometry_msgs/msg/Vector3Stamped", False),
    T.SCENE_STRUCTURE: ("raspv_msgs/msg/SceneStructure", False),
    T.SCENE_LABELS: ("sensor_msgs/msg/Image", False),
    T.STAIRS: ("raspv_msgs/msg/StairDetection", False),
    T.SEGMENTATION_LABELS: ("sensor_msgs/msg/Image", False),
    T.SEGMENTATION_CLASSES: ("raspv_msgs/msg/ClassNames", True),
    T.NAV_PATH: ("nav_msgs/msg/Path", False),
    T.NAV_CMD_VEL_HINT: ("geometry_msgs/msg/Twist", False),
    T.NAV_GUIDANCE: ("raspv_msgs/msg/NavGuidance", False),
    T.NAV_GLOBAL_COSTMAP: ("nav_msgs/msg/OccupancyGrid", True),
    T.NAV_COSTMAP: ("nav_msgs/msg/OccupancyGrid", False),
    T.NAV_OBSTACLE_LAYER: ("nav_msgs/msg/OccupancyGrid", False),
    T.SPV_IMAGE: ("sensor_msgs/msg/Image", False),
    T.SPV_FRAME: ("raspv_msgs/msg/PhospheneFrame", False),
    T.SPV_MAP: ("raspv_msgs/msg/PhospheneMap", True),
    T.SPV_SPRITES: ("raspv_msgs/msg/PhospheneSprites", True),
    T.SPV_STATUS: ("std_msgs/msg/String", True),
    T.HMD_PRESENTATION: ("std_msgs/msg/String", False),
    T.VIZ_SCENE: ("visualization_msgs/msg/MarkerArray", False),
    T.VIZ_STAIRS: ("visualization_msgs/msg/MarkerArray", False),
    T.VIZ_PATH: ("visualization_msgs/msg/MarkerArray", False),
    T.VIZ_PHOSPHENES: ("visualization_msgs/msg/MarkerArray", False),
    T.VIZ_CLOUD: ("sensor_msgs/msg/PointCloud2", False),
    T.SLAM_STATE: ("std_msgs/msg/String", True),
    T.SLAM_MARKERS: ("visualization_msgs/msg/MarkerArray", False),
    T.TF: ("tf2_msgs/msg/TFMessage", False),
    T.TF_STATIC: ("tf2_msgs/msg/TFMessage", True),
    T.CLOCK: ("rosgraph_msgs/msg/Clock", False),
    T.EXPERIMENT_INSTRUCTIONS: ("std_msgs/msg/String", True),
    T.EXPERIMENT_RESPONSE: ("std_msgs/msg/String", False),
}
SERVICES = frozenset({T.SIM_START_TRIAL, T.SIM_END_TRIAL, T.SLAM_SAVE_MAP})   # in raspv_common.topics, not topics


def known_topics(wants) -> list[tuple[str, str, bool]]:
    """(name, type, latched) of the known topics that ``wants(name)`` selects, sorted by name."""
    return [(name, msgtype, latched) for name, (msgtype, latched) in sorted(KNOWN_TOPICS.items()) if wants(name)]
