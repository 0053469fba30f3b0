"""Marker shapes and packed clouds → ``visualization_msgs/MarkerArray`` and
``sensor_msgs/PointCloud2`` (no rclpy: message classes only)."""
from __future__ import annotations

import array

import numpy as np
from geometry_msgs.msg import Point, Vector3
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from raspv_common.conversions import matrix_to_pose
from raspv_viz.cloud import FLOAT32, pack_cloud
from raspv_viz.shapes import CUBE, LINE_LIST, LINE_STRIP, SPHERE, SPHERE_LIST, TRIANGLE_LIST, MarkerShape

MARKER_TYPES = {LINE_STRIP: Marker.LINE_STRIP, LINE_LIST: Marker.LINE_LIST, TRIANGLE_LIST: Marker.TRIANGLE_LIST,
                CUBE: Marker.CUBE, SPHERE: Marker.SPHERE, SPHERE_LIST: Marker.SPHERE_LIST}


def to_marker(shape: MarkerShape, header: Header) -> Marker:
    m = Marker(header=header, ns=shape.ns, id=int(shape.id), type=MARKER_TYPES[shape.kind], action=Marker.ADD)
    m.pose = matrix_to_pose(shape.pose)
    m.scale = Vector3(x=float(shape.scale[0]), y=float(shape.scale[1]), z=float(shape.scale[2]))
    r, g, b, a = (float(c) for c in shape.color)
    m.color = ColorRGBA(r=r, g=g, b=b, a=a)
    m.points = [Point(x=x, y=y, z=z) for x, y, z in np.asarray(shape.points, dtype=np.float64).tolist()]
    if shape.colors is not None:
        m.colors = [ColorRGBA(r=r, g=g, b=b, a=a) for r, g, b, a in np.asarray(shape.colors, dtype=np.float64).tolist()]
    return m


def marker_array(shapes: list[MarkerShape], header: Header) -> MarkerArray:
    """A DELETEALL first (what the previous array drew on this topic goes), then the shapes."""
    return MarkerArray(markers=[Marker(header=header, action=Marker.DELETEALL),
                                *(to_marker(s, header) for s in shapes)])


def point_cloud(points: np.ndarray, colors: np.ndarray | None, header: Header) -> PointCloud2:
    fields, step, data = pack_cloud(points, colors)
    msg = PointCloud2(header=header, height=1, width=len(points), is_bigendian=False, point_step=step,
                      row_step=step * len(points), is_dense=True)
    msg.fields = [PointField(name=name, offset=offset, datatype=FLOAT32, count=1) for name, offset in fields]
    msg.data = array.array("B", data)
    return msg
