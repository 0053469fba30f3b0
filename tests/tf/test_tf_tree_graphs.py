"""The tf tree of shipped graphs, as a tf listener sees it: every frame_id a topic of the graph
uses is connected to ``map`` by what the graph publishes on /tf and /tf_static, and the
transforms place the camera where ``/camera/pose`` says it is. /tf is announced with upstream's
TFMessage type hash (what a system ROS 2 matches publishers by)."""
from __future__ import annotations

import threading
import time

import pytest
import yaml
from geometry_msgs.msg import PoseStamped
from tf2_msgs.msg import TFMessage

from raspv_bags.known_topics import KNOWN_TOPICS
from raspv_bringup.graph import CONFIG_DIR
from raspv_bringup.testing import Collector
from raspv_common import frames, topics
from raspv_common.conversions import pose_to_matrix, stamp_to_seconds, transform_to_matrix
from raspv_common.qos import LATCHED_QOS, SENSOR_QOS, TF_QOS, TF_STATIC_LISTENER_QOS
from raspv_common.ros_introspection import message_class
from raspv_common.transform_tree import TransformTree
from tests.tf.test_tf2_msgs import UPSTREAM

pytestmark = pytest.mark.integration


class _Callback(Collector):
    """A probe subscription that hands each message to ``fn`` instead of keeping it (released
    with the probe's at the end of the test)."""

    def __init__(self, fn) -> None:
        super().__init__()
        self._fn = fn

    def _add(self, msg) -> None:
        self._fn(msg)


def watch_topic(probe, topic: str, cls, qos, fn) -> None:
    col = _Callback(fn)
    col.subscription = probe.node.create_subscription(cls, topic, col._add, qos)
    probe._collectors.append(col)


class FrameWatch:
    """Every frame_id seen on the graph's known topics, and a tf tree of /tf and /tf_static."""

    def __init__(self, probe) -> None:
        self.frames: dict[str, set[str]] = {}          # frame_id → topics naming it
        self.tree = TransformTree(max_age_s=30.0)
        self.lock = threading.Lock()
        for topic, (msgtype, latched) in KNOWN_TOPICS.items():
            if topic in (topics.TF, topics.TF_STATIC):
                continue
            try:
                cls = message_class(msgtype)
            except ValueError:
                continue
            watch_topic(probe, topic, cls, LATCHED_QOS if latched else SENSOR_QOS, lambda m, t=topic: self._seen(t, m))
        watch_topic(probe, topics.TF, TFMessage, TF_QOS, lambda m: self._tf(m, False))
        watch_topic(probe, topics.TF_STATIC, TFMessage, TF_STATIC_LISTENER_QOS, lambda m: self._tf(m, True))

    def _seen(self, topic: str, msg) -> None:
        headers = [m.header for m in msg.markers] if hasattr(msg, "markers") else [getattr(msg, "header", None)]
        names = {h.frame_id for h in headers if h is not None and h.frame_id}
        if getattr(msg, "child_frame_id", ""):
            names.add(msg.child_frame_id)
        with self.lock:
            for name in names:
                self.frames.setdefault(name, set()).add(topic)

    def _tf(self, msg: TFMessage, static: bool) -> None:
        with self.lock:
            for t in msg.transforms:
                self.tree.set(t.header.frame_id, t.child_frame_id, transform_to_matrix(t.transform),
                              stamp_to_seconds(t.header.stamp), static=static)

    def unconnected(self) -> dict[str, list[str]]:
        with self.lock:
            return {f: sorted(t) for f, t in self.frames.items() if not self.tree.connected(f, frames.MAP)}

    def wait_for(self, wanted: set[str], timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                seen = set(self.frames)
            if wanted <= seen and not self.unconnected():
                return
            time.sleep(0.1)


def test_navigation_graph_with_viz_has_one_tree_from_map_to_every_frame_it_uses(graph, probe):
    doc = yaml.safe_load((CONFIG_DIR / "navigation.yaml").read_text())
    doc["launch"]["nodes"].append({"kind": "viz"})
    doc["sim"]["ros__parameters"].update({"width": 160, "height": 120})
    watch = FrameWatch(probe)
    graph(doc)
    used = {frames.MAP, frames.ODOM, frames.BASE_LINK, frames.CAMERA_OPTICAL}   # poses, /odom, images, markers
    watch.wait_for(used, timeout=120)
    assert used <= set(watch.frames), watch.frames
    assert not watch.unconnected(), (watch.unconnected(), watch.tree.edges())
    assert set(watch.tree.chain(frames.CAMERA_OPTICAL)) == {frames.CAMERA_OPTICAL, frames.CAMERA_LINK, frames.HEAD,
                                                             frames.BASE_LINK, frames.ODOM, frames.MAP}
    # the tree puts the camera where /camera/pose says it is (ground truth, the same frame)
    pose = probe.wait_for_message(topics.CAMERA_POSE, PoseStamped, timeout=30)
    stamp = stamp_to_seconds(pose.header.stamp)
    deadline = time.monotonic() + 30
    while (T := watch.tree.lookup_or_none(frames.MAP, frames.CAMERA_OPTICAL, stamp)) is None \
            and time.monotonic() < deadline:
        time.sleep(0.05)
    assert T is not None and T == pytest.approx(pose_to_matrix(pose.pose), abs=1e-6)
    [info] = probe.node.get_publishers_info_by_topic(topics.TF)[:1]
    assert str(info.topic_type_hash) == UPSTREAM
