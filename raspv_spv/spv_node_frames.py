"""The spv node's place in the graph's frames (ROS side): the phosphene image in tf, and the
localisation state in ``/spv/status``.

The phosphene image (frame ``phosphene`` of /spv/image, /spv/frame, /spv/map) is a pinhole view
from the camera's centre along its optical axes (the phosphenes sample the camera's rays,
K_C·K_P⁻¹), so the node publishes ``<camera optical frame> → phosphene`` (identity) on
/tf_static once camera info names that frame: RViz and Foxglove can lay it over the scene.

A graph whose pose comes from the `slam` node publishes its tracking state on ``/slam/state``
(std_msgs/String JSON, transient-local: ``{"state": "tracking" | "lost" | "new_map" | …,
"map_id": 0, …}``). The spv node keeps the newest and puts ``{"localisation": {"source": "slam",
"state": …, "map_id": …}}`` into its latched ``/spv/status`` (``map_id`` when the slam node
sends one: another than 0 means the poses are in a new sub-map's frame, not the first map's),
published again when either changes (not on every frame). A graph without a
slam node has no such key. A mixin of :class:`raspv_spv.spv_node.SpvNode`.
"""
from __future__ import annotations

import json

import numpy as np
from sensor_msgs.msg import CameraInfo
from std_msgs.msg import String

from raspv_common import topics
from raspv_common.qos import LATCHED_QOS
from raspv_common.tf_messages import StaticTfBroadcaster

PHOSPHENE_FRAME = "phosphene"


class SpvFrames:
    """The phosphene frame in tf and the localisation state in /spv/status (see the module docstring)."""

    def _setup_frames(self) -> None:
        self.localisation: dict | None = None
        self._phosphene_parent = ""
        self._static_tf = StaticTfBroadcaster(self)
        self.create_subscription(String, topics.SLAM_STATE, self.on_slam_state, LATCHED_QOS)

    def on_camera_info(self, msg: CameraInfo) -> None:
        """The camera model, and the phosphene frame on the optical frame camera info names (sent
        once per name)."""
        super().on_camera_info(msg)
        parent = msg.header.frame_id
        if parent and parent != self._phosphene_parent:
            self._phosphene_parent = parent
            self._static_tf.send([(parent, PHOSPHENE_FRAME, np.eye(4))])

    def on_slam_state(self, msg: String) -> None:
        try:
            doc = json.loads(msg.data)
            state = doc["state"]
            map_id = doc.get("map_id")
        except (json.JSONDecodeError, KeyError, TypeError, AttributeError):
            self.warn_throttled("slam-state", f"ignoring {topics.SLAM_STATE}: not a JSON object with a 'state'")
            return
        localisation = {"source": "slam", "state": str(state)}
        if isinstance(map_id, int) and not isinstance(map_id, bool):
            localisation["map_id"] = map_id
        if localisation == self.localisation:
            return
        self.localisation = localisation
        shown = getattr(self, "_shown", None)
        if shown is not None:
            self._publish_status(shown[2], shown[0].config.mode, self.producers.states())
