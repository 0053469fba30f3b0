"""The bridge's audio-cue relay: navigation guidance and stairs → ``cues`` messages to the clients.

Subscribes ``/nav/guidance`` (raspv_msgs/NavGuidance, world frame W), ``/stairs``
(raspv_msgs/StairDetection, camera frame), ``/odom`` and ``/camera/pose`` (stamped poses kept in
:class:`~raspv_common.pose_buffer.PoseBuffer`\\ s), and at ``rate`` Hz sends every client a
``cues`` message built by :func:`raspv_hmd.audio_cues.cues_message`: in the avatar's base frame
when ``/odom`` arrives (the client turns the listener with its own head orientation), else in
the camera's frame. Guidance or stairs older than ``STALE_S`` seconds (data time) are left out.
"""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from raspv_msgs.msg import NavGuidance, StairDetection

from raspv_common import topics
from raspv_common.conversions import pose_to_matrix, stamp_to_seconds
from raspv_common.pose_buffer import PoseBuffer
from raspv_common.qos import SENSOR_QOS
from raspv_hmd.audio_cues import CueSettings, cues_message

STALE_S = 1.5


class CueRelay:
    def __init__(self, node, server, settings: CueSettings, rate: float = 10.0) -> None:
        from raspv_nav.nav_msg import guidance_from_msg
        from raspv_perception.stairs_msg import staircase_from_msg

        self.node, self.server, self.settings = node, server, settings
        self._guidance_from_msg, self._staircase_from_msg = guidance_from_msg, staircase_from_msg
        self.base_poses = PoseBuffer(max_age_s=5.0, max_extrapolation_s=0.2)
        self.camera_poses = PoseBuffer(max_age_s=5.0, max_extrapolation_s=0.2)
        self.guidance = None
        self.stairs: tuple[float, object] | None = None          # (stamp, Staircase or None)
        self.sent = 0
        self.rate = rate
        self._listening = False
        node.create_subscription(NavGuidance, topics.NAV_GUIDANCE, self.on_guidance, SENSOR_QOS)
        node.create_subscription(StairDetection, topics.STAIRS, self.on_stairs, SENSOR_QOS)

    def _listen(self) -> None:
        """The poses and the cue timer, once there is something to cue (a graph without navigation
        or stairs pays nothing: 40 pose messages and 10 timer wake-ups a second in rclpy's executor
        cost the bridge ~10 % of a core)."""
        if self._listening:
            return
        self._listening = True
        self.node.create_subscription(Odometry, topics.ODOM, self.on_odom, SENSOR_QOS)
        self.node.create_subscription(PoseStamped, topics.CAMERA_POSE, self.on_camera_pose, SENSOR_QOS)
        self.node.create_timer(1.0 / self.rate, self.send)

    def on_guidance(self, msg: NavGuidance) -> None:
        self.guidance = self._guidance_from_msg(msg)
        self._listen()

    def on_stairs(self, msg: StairDetection) -> None:
        self.stairs = (stamp_to_seconds(msg.header.stamp), self._staircase_from_msg(msg))
        if self.stairs[1] is not None:
            self._listen()

    def on_odom(self, msg: Odometry) -> None:
        try:
            self.base_poses.add(stamp_to_seconds(msg.header.stamp), pose_to_matrix(msg.pose.pose))
        except ValueError:
            pass

    def on_camera_pose(self, msg: PoseStamped) -> None:
        try:
            self.camera_poses.add(stamp_to_seconds(msg.header.stamp), pose_to_matrix(msg.pose))
        except ValueError:
            pass

    def _pose(self, buffer: PoseBuffer, stamp: float | None) -> np.ndarray | None:
        latest = buffer.latest()
        if latest is None:
            return None
        if stamp is None:
            return latest.matrix
        pose = buffer.lookup_or_none(stamp)
        return pose if pose is not None else latest.matrix

    def message(self) -> dict | None:
        """The cues for the newest data, or None when there is nothing to say."""
        newest = max([s.stamp for s in (self.base_poses.latest(), self.camera_poses.latest()) if s is not None],
                     default=None)
        if newest is None:
            return None
        guidance = self.guidance if self.guidance is not None and newest - self.guidance.stamp <= STALE_S else None
        stairs_stamp, stairs = self.stairs if self.stairs is not None else (None, None)
        if stairs is not None and newest - stairs_stamp > STALE_S:
            stairs = None
        if guidance is None and stairs is None:
            return None
        stamp = guidance.stamp if guidance is not None else stairs_stamp
        frame = "base" if len(self.base_poses) else "head"
        listener = self._pose(self.base_poses if frame == "base" else self.camera_poses, stamp)
        listener_from_camera = None
        if stairs is not None and frame == "base":
            base, camera = self._pose(self.base_poses, stairs_stamp), self._pose(self.camera_poses, stairs_stamp)
            if base is None or camera is None:
                stairs = None
            else:
                listener_from_camera = np.linalg.inv(base) @ camera
        return cues_message(guidance, listener, frame, stairs, listener_from_camera, self.settings)

    def send(self) -> None:
        msg = self.message()
        if msg is not None:
            self.server.broadcast("cues", **msg)
            self.sent += 1
