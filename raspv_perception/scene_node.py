"""`scene` node: depth + camera info (+ optional /camera/pose and /camera/imu priors) →
/scene/structure and /scene/labels.

Each depth image is processed on arrival (the newest wins when processing is slower than the
source); with ``lockstep`` (scripted sessions) it waits for the /camera/pose of its own stamp
(:mod:`raspv_perception.pose_pairing`), so every run processes a frame with the same prior.
The pose prior is the /camera/pose nearest the depth stamp, within ``pose_max_age``;
the gravity prior is the low-passed accelerometer of /camera/imu (``imu_gravity``) when its
samples are recent and in the depth image's frame. ``mounting`` sets the first-floor limits.
Both outputs carry the depth image's header, so consumers pair them by stamp.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np
from geometry_msgs.msg import PoseStamped
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from sensor_msgs.msg import CameraInfo, Image, Imu

from raspv_common import topics
from raspv_common.conversions import (array_to_image, pose_to_matrix, stamp_to_seconds)
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import IMU_QOS, LATEST_QOS, SENSOR_QOS
from raspv_perception.imu_gravity import GravityFilter
from raspv_perception.pose_pairing import PosePairing
from raspv_perception.scene_config import SceneConfig
from raspv_perception.scene_msg import structure_to_msg
from raspv_perception.scene_params import CONFIG_FIELDS, PARAMS
from raspv_perception.scene_perception import ScenePerception


IMU_SETTLE_S = 1.0     # longest wait for IMU gravity before the first frame is processed without it [s]


def config_from_params(p: dict) -> SceneConfig:
    """SceneConfig from node parameters (ValueError with the reason if inconsistent): the
    explicit fields, then the first-floor limits of ``mounting`` (unless it is ``custom``)."""
    config = dataclasses.replace(SceneConfig(), **{k: p[k] for k in CONFIG_FIELDS})
    defaults = {k: getattr(SceneConfig(), k) for k in ("first_floor_min_height", "first_floor_max_height",
                                                        "first_floor_max_angle_deg")}
    changed = [k for k, v in defaults.items() if p[k] != v]
    if changed and p["mounting"] != "custom":
        raise ValueError(f"{', '.join(changed)} applies with mounting 'custom' (mounting is {p['mounting']!r}: "
                         f"set mounting to custom, or keep the mounting's limits)")
    return config.with_mounting(p["mounting"])


class SceneNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("scene", PARAMS)
        try:
            self.perception = ScenePerception(config_from_params(self.params))
        except ValueError as exc:
            raise ConfigurationError(str(exc)) from None
        self.pairing = PosePairing(self.params["pose_max_age"],
                                   wait=self.params["lockstep"] and self.params["use_pose_prior"])
        self.gravity = GravityFilter()
        self.imu_frame: str | None = None
        self.imu_since: float | None = None      # monotonic time of the first /camera/imu message
        self.frames = 0
        self.pub_structure = self.create_publisher(SceneStructureMsg, topics.SCENE_STRUCTURE, SENSOR_QOS)
        self.pub_labels = self.create_publisher(Image, topics.SCENE_LABELS, SENSOR_QOS)
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self.on_camera_info, SENSOR_QOS)
        self.create_subscription(PoseStamped, topics.CAMERA_POSE, self.on_pose, SENSOR_QOS)
        self.create_subscription(Imu, topics.IMU, self.on_imu, IMU_QOS)
        self.create_subscription(Image, topics.DEPTH, self.on_depth, LATEST_QOS)    # the newest frame when behind

    def on_parameters(self, changes):
        try:
            config = config_from_params({**self.params, **changes})
        except ValueError as exc:
            return str(exc)
        self.perception.set_config(config)
        if "pose_max_age" in changes:
            self.pairing.max_age_s = changes["pose_max_age"]
        return None


    def on_pose(self, msg: PoseStamped) -> None:
        T = pose_to_matrix(msg.pose)
        if not np.isfinite(T).all():
            self.warn_throttled("pose", "ignoring a camera pose with NaN/inf values")
            return
        released = self.pairing.add_pose(stamp_to_seconds(msg.header.stamp), T)
        if released is not None:
            self._process(released[1])

    def on_imu(self, msg: Imu) -> None:
        a = msg.linear_acceleration
        self.imu_frame = msg.header.frame_id
        if self.imu_since is None:
            self.imu_since = time.monotonic()
        self.gravity.add(stamp_to_seconds(msg.header.stamp), (a.x, a.y, a.z))

    def _gravity_up(self, msg: Image) -> tuple[np.ndarray | None, bool]:
        """(IMU up direction in C or None, whether to wait for it): while an IMU publishes but
        its gravity has not settled (at most IMU_SETTLE_S), frames wait, so that the first
        floor is not chosen by the mounting's limits alone."""
        if not self.params["use_imu"] or self.imu_frame is None:
            return None, False
        if self.imu_frame != msg.header.frame_id:
            self.warn_throttled("imu-frame", f"ignoring {topics.IMU}: frame {self.imu_frame!r} is not the depth "
                                             f"image's {msg.header.frame_id!r} (no transforms here)", period_s=60.0)
            return None, False
        up = self.gravity.up(stamp_to_seconds(msg.header.stamp))
        wait = up is None and self.frames == 0 and time.monotonic() - self.imu_since < IMU_SETTLE_S
        return up, wait

    def _prior(self, stamp: float) -> np.ndarray | None:
        return self.pairing.prior(stamp) if self.params["use_pose_prior"] else None

    def on_depth(self, msg: Image) -> None:
        if self.intrinsics is None:
            self.warn_throttled("no-info", f"waiting for {topics.CAMERA_INFO}")
            return
        ready = self.pairing.add_frame(stamp_to_seconds(msg.header.stamp), msg)
        if ready is not None:
            self._process(ready[1])

    def _process(self, msg: Image) -> None:
        """Analyse one depth frame and publish its structure and labels."""
        depth = self.read_depth(msg)
        if depth is None:
            return
        K = self.intrinsics
        up, wait = self._gravity_up(msg)
        if wait:
            return
        result = self.perception.process(depth, K, self._prior(stamp_to_seconds(msg.header.stamp)), up)
        self.pub_structure.publish(structure_to_msg(result.structure, msg.header))
        if self.params["publish_labels"]:
            self.pub_labels.publish(array_to_image(result.labels, "mono8", msg.header))
        self.frames += 1
        if self.frames == 1:
            s = result.structure
            floor = (f"floor {s.camera_height:.2f} m below, pitch {s.camera_pitch_deg:.0f} deg" if s.floor_found
                     else f"no floor (mounting {self.params['mounting']})")
            floor += f", gravity from {s.gravity_source.name.lower()}"
            self.get_logger().info(f"first frame {K.width}x{K.height}: {floor}, {len(s.planes)} planes, "
                                   f"{len(s.obstacles)} obstacles, {s.processing_ms:.0f} ms")


def main(argv=None) -> None:
    run_node(SceneNode, argv, priority="perception")


if __name__ == "__main__":
    main()
