"""The spv node's input callbacks (ROS side): each message is checked and converted (a bad one is
skipped with one rate-limited warning), kept with its stamp, and the frame it completes is
computed (:meth:`raspv_spv.spv_node.SpvNode._frame_arrived`). Camera poses and odometry go into
the display view's tracker (a frame shown with a predicted pose is recomputed when its own
comes); a head turn is shown at once. A mixin of :class:`raspv_spv.spv_node.SpvNode`.
"""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseStamped, QuaternionStamped
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMsg
from sensor_msgs.msg import Image

from raspv_common import topics
from raspv_common.conversions import (ImageEncodingError, depth_from_image, image_to_array, pose_to_matrix,
                                      rgb_from_image, stamp_to_seconds)
from raspv_common.frames import is_map_frame
from raspv_msgs.msg import ClassNames, NavGuidance, StairDetection
from raspv_msgs.msg import SceneStructure as SceneStructureMsg
from raspv_nav.nav_msg import guidance_from_msg
from raspv_perception.scene_msg import structure_from_msg
from raspv_perception.segmentation_msg import classes_from_msg
from raspv_perception.stairs_msg import staircase_from_msg
from raspv_spv.reprojection import STAMP_TOLERANCE_S as POSE_TOLERANCE_S

HEAD_POKE_COS = float(np.cos(np.radians(0.1) / 2))  # a head turn of more than 0.1° is shown at once


class SpvInputs:
    def on_color(self, msg: Image) -> None:
        try:
            self.color = rgb_from_image(msg)
        except ImageEncodingError as exc:
            self.warn_throttled("color", f"ignoring colour image on {topics.COLOR}: {exc}")
            return
        self.stamps["color"] = stamp_to_seconds(msg.header.stamp)
        self._arrived("color")
        self._take_pending_poses()
        self._frame_arrived("color")

    def on_depth(self, msg: Image) -> None:
        try:
            self.depth = depth_from_image(msg)
        except ImageEncodingError as exc:
            self.warn_throttled("depth", f"ignoring depth image on {topics.DEPTH}: {exc}")
            return
        self.stamps["depth"] = stamp_to_seconds(msg.header.stamp)
        self._arrived("depth")
        self._take_pending_poses()
        self._frame_arrived("depth")

    def _take_pending_poses(self) -> None:
        """Camera poses and odometry already waiting are taken before a frame is computed: the
        executor may hand the frame over first, and a frame whose pose is not in is computed with
        one predicted from the poses before it — after a head turn, the old direction — and shown
        re-projected from the head of its stamp until its own pose comes."""
        for name, callback in (("camera_pose", self.on_pose), ("odom", self.on_odom)):
            sub = self._subs.get(name)
            while sub is not None and (msg := self.take_pending(sub)) is not None:
                callback(msg)

    def on_pose(self, msg: PoseStamped) -> None:
        stamp = stamp_to_seconds(msg.header.stamp)
        try:
            pose = pose_to_matrix(msg.pose)
            self.view.tracker.add_camera_pose(stamp, pose)
        except ValueError as exc:
            self.warn_throttled("pose", f"ignoring camera pose: {exc}")
            return
        self.pose = pose
        pending = self._pending
        if pending is not None and stamp >= pending.stamp - POSE_TOLERANCE_S:
            newest = self.view.newest_frame()
            if self._pending_shown and (newest is None or newest.stamp != pending.stamp):
                self._pending = None                # a newer frame is already shown: nothing to correct
            else:
                self._finish_frame(pending)         # with its own pose (again, if shown with a predicted one)

    def on_head(self, msg: QuaternionStamped) -> None:
        q = msg.quaternion
        try:
            self.view.tracker.add_head(stamp_to_seconds(msg.header.stamp), (q.x, q.y, q.z, q.w))
        except ValueError as exc:
            self.warn_throttled("head", f"ignoring {topics.HEAD_ORIENTATION}: {exc}")
            return
        quat = np.array([q.x, q.y, q.z, q.w])
        quat /= np.linalg.norm(quat)
        if self._shown_head is None or abs(float(quat @ self._shown_head)) < HEAD_POKE_COS:
            self._shown_head = quat         # the head turned: show it now, not at the next tick
            self.clock.poke()

    def on_odom(self, msg: Odometry) -> None:
        try:
            self.view.tracker.add_odometry(stamp_to_seconds(msg.header.stamp), pose_to_matrix(msg.pose.pose),
                                           msg.twist.twist.angular.z)
        except ValueError as exc:
            self.warn_throttled("odom", f"ignoring {topics.ODOM}: {exc}")

    def on_nav_path(self, msg: PathMsg) -> None:
        """The navigation path (world frame) as an (N, 3) array for the path overlay."""
        if not is_map_frame(msg.header.frame_id):
            self.warn_throttled("path", f"ignoring {topics.NAV_PATH} in frame {msg.header.frame_id!r}; expected 'map'")
            return
        self.extras["nav_path"] = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z]
                                            for p in msg.poses], dtype=float).reshape(-1, 3)
        self._arrived("nav_path")

    def on_nav_guidance(self, msg: NavGuidance) -> None:
        """The navigation assistant's guidance (world frame) for the guidance overlay."""
        self.extras["nav_guidance"] = guidance_from_msg(msg)
        self._arrived("nav_guidance")

    def on_stairs(self, msg: StairDetection) -> None:
        """The newest staircase detection (camera frame of its depth image) for the stairs overlay;
        each frame moves it into its own camera frame (:meth:`_finish_frame`)."""
        stair = staircase_from_msg(msg)
        self.extras["stairs"] = [] if stair is None else [stair]
        self.stamps["stairs"] = stamp_to_seconds(msg.header.stamp)
        self._arrived("stairs")

    def on_segmentation(self, msg: Image) -> None:
        """Keep the last label images with their stamps (the highlight overlay takes the one of
        its frame); when the labels of the frame the levels came from arrive late, redo them."""
        try:
            labels = image_to_array(msg)
        except ImageEncodingError as exc:
            self.warn_throttled("segmentation", f"ignoring {topics.SEGMENTATION_LABELS}: {exc}")
            return
        stamp = stamp_to_seconds(msg.header.stamp)
        self._arrived("segmentation")
        self.extras["segmentation"] = (tuple(self.extras.get("segmentation", ())) + ((stamp, labels),))[-8:]
        newest = self.view.newest_frame()
        if newest is not None and abs(newest.stamp - stamp) < 1e-6:
            which = next((k for k, t in self.stamps.items() if abs(t - stamp) < 1e-6), None)
            if which is not None:
                self._frame_arrived(which)

    def on_segmentation_classes(self, msg: ClassNames) -> None:
        try:
            self.extras["segmentation_classes"] = classes_from_msg(msg)
        except ValueError as exc:
            self.warn_throttled("segmentation", f"ignoring {topics.SEGMENTATION_CLASSES}: {exc}")

    def on_scene(self, msg: SceneStructureMsg) -> None:
        self.scene = structure_from_msg(msg)
        self.stamps["scene"] = stamp_to_seconds(msg.header.stamp)
        self._arrived("scene")
        self._frame_arrived("scene")

    def on_scene_labels(self, msg: Image) -> None:
        if msg.encoding not in ("mono8", "8UC1"):
            self.warn_throttled("labels", f"ignoring {topics.SCENE_LABELS}: expected mono8, got {msg.encoding!r}")
            return
        try:
            self.scene_labels = image_to_array(msg)
        except ImageEncodingError as exc:
            self.warn_throttled("labels", f"ignoring {topics.SCENE_LABELS}: {exc}")
            return
        self.stamps["scene_labels"] = stamp_to_seconds(msg.header.stamp)
        self._arrived("scene_labels")
        self._frame_arrived("scene_labels")
