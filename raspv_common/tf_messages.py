"""Publishing and reading tf (``tf2_msgs/TFMessage`` on /tf and /tf_static) without tf2_ros.

A node owning transforms publishes them with :class:`TfBroadcaster` (moving ones, /tf, stamped
with the data they belong to) and :class:`StaticTfBroadcaster` (mountings, /tf_static: all of a
node's static transforms in one transient-local message, re-sent whole when one is added, as
tf2_ros does). :class:`TfListener` fills a :class:`~raspv_common.transform_tree.TransformTree`
from both topics. Frame names: :mod:`raspv_common.frames`.
"""
from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage

from raspv_common import topics
from raspv_common.conversions import stamp_to_seconds, transform_to_matrix
from raspv_common.qos import TF_QOS, TF_STATIC_LISTENER_QOS, TF_STATIC_QOS
from raspv_common.rotations import matrix_to_quaternion
from raspv_common.transform_tree import TransformTree

Edge = tuple[str, str, np.ndarray]          # (parent, child, 4×4 parent ← child)


def transform_msg(parent: str, child: str, matrix: np.ndarray, stamp: Time) -> TransformStamped:
    T = np.asarray(matrix, dtype=float)
    qx, qy, qz, qw = matrix_to_quaternion(T[:3, :3])
    x, y, z = (float(v) for v in T[:3, 3])
    return TransformStamped(header=Header(stamp=stamp, frame_id=parent), child_frame_id=child,
                            transform=Transform(translation=Vector3(x=x, y=y, z=z),
                                                rotation=Quaternion(x=qx, y=qy, z=qz, w=qw)))


class TfBroadcaster:
    """Moving transforms on /tf, stamped with the data they belong to."""

    def __init__(self, node) -> None:
        self.publisher = node.create_publisher(TFMessage, topics.TF, TF_QOS)

    def send(self, edges: list[Edge], stamp: Time) -> None:
        self.publisher.publish(TFMessage(transforms=[transform_msg(p, c, T, stamp) for p, c, T in edges]))


class StaticTfBroadcaster:
    """A node's fixed transforms on /tf_static: one transient-local message holding all of them."""

    def __init__(self, node) -> None:
        self.node = node
        self.publisher = node.create_publisher(TFMessage, topics.TF_STATIC, TF_STATIC_QOS)
        self._by_child: dict[str, TransformStamped] = {}

    def send(self, edges: list[Edge]) -> None:
        """Add (or replace, by child frame) ``edges`` and publish the whole set again."""
        stamp = self.node.get_clock().now().to_msg()
        for parent, child, T in edges:
            self._by_child[child] = transform_msg(parent, child, T, stamp)
        self.publisher.publish(TFMessage(transforms=list(self._by_child.values())))


class TfListener:
    """Keeps a :class:`TransformTree` of everything on /tf and /tf_static."""

    def __init__(self, node, tree: TransformTree | None = None) -> None:
        self.tree = tree if tree is not None else TransformTree()
        self._node = node
        node.create_subscription(TFMessage, topics.TF, lambda m: self._on(m, False), TF_QOS)
        node.create_subscription(TFMessage, topics.TF_STATIC, lambda m: self._on(m, True), TF_STATIC_LISTENER_QOS)

    def _on(self, msg: TFMessage, static: bool) -> None:
        for t in msg.transforms:
            try:
                self.tree.set(t.header.frame_id, t.child_frame_id, transform_to_matrix(t.transform),
                              stamp_to_seconds(t.header.stamp), static=static)
            except ValueError as exc:
                self._node.warn_throttled(f"tf:{t.child_frame_id}", f"ignoring transform: {exc}", period_s=30.0)


MOUNTING_GRACE_S = 2.0     # s: how long a pose node waits for base_link ← camera in tf before assuming the camera is the body


class CameraPoseTf:
    """tf of a node that tracks the camera (slam, odometry): ``map → odom`` and ``odom → base_link``.

    The node knows odom ← C (the optical frame of its images); ``base_link ← C`` comes from the
    tf tree at the image's stamp (the camera's mounting from /tf_static, a turning head from
    /tf). Until it is known the transforms wait; when none came ``MOUNTING_GRACE_S`` after the
    first frame, the camera is taken as the body (``base_link`` = ``camera_link``, warned once).
    ``static_map_odom``: publish ``map → odom`` once as identity on /tf_static (a pose that does
    not drift: the odometry node), else with every pose on /tf (the slam node's correction).
    """

    def __init__(self, node, static_map_odom: bool) -> None:
        from raspv_common import frames

        self.frames = frames
        self.node = node
        self.listener = TfListener(node)
        self.broadcaster = TfBroadcaster(node)
        self.static_map_odom = static_map_odom
        if static_map_odom:
            StaticTfBroadcaster(node).send([(frames.MAP, frames.ODOM, np.eye(4))])
        self._first_stamp: float | None = None
        self._assumed = False

    def base_from_camera(self, camera_frame: str, stamp: float) -> np.ndarray | None:
        f = self.frames
        T = self.listener.tree.lookup_or_none(f.BASE_LINK, camera_frame, stamp)
        if T is not None:
            return T
        if self._first_stamp is None:
            self._first_stamp = stamp
        if stamp - self._first_stamp < MOUNTING_GRACE_S and not self._assumed:
            return None
        if not self._assumed:
            self._assumed = True
            self.node.get_logger().warning(
                f"no transform {f.BASE_LINK} ← {camera_frame!r} in /tf after {MOUNTING_GRACE_S:g} s: taking the camera "
                f"as the body ({f.BASE_LINK} = {f.CAMERA_LINK}); the source publishes its mounting on /tf_static")
        return f.LINK_FROM_OPTICAL

    def publish(self, stamp: Time, camera_frame: str, odom_from_camera: np.ndarray,
                map_from_odom: np.ndarray | None = None) -> bool:
        """Send odom → base_link (and map → odom unless static) for a frame of ``camera_frame`` at
        ``stamp``; False while base_link ← camera is not known yet."""
        f = self.frames
        base_from_camera = self.base_from_camera(camera_frame or f.CAMERA_OPTICAL, stamp_to_seconds(stamp))
        if base_from_camera is None:
            return False
        edges = [(f.ODOM, f.BASE_LINK, odom_from_camera @ np.linalg.inv(base_from_camera))]
        if not self.static_map_odom:
            edges.insert(0, (f.MAP, f.ODOM, np.eye(4) if map_from_odom is None else map_from_odom))
        self.broadcaster.send(edges, stamp)
        return True
