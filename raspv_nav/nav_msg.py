"""Navigation results ↔ standard messages (no rclpy: message classes only).

- paths: ``nav_msgs/Path`` (frame W of the poses, z = 0 on the floor);
- costmaps: ``nav_msgs/OccupancyGrid`` in W — the grid lives in the map frame M, so its
  ``info.origin`` is the pose in W of cell (0, 0)'s corner (rotated when M is), and RViz or
  Foxglove draw it where the path is;
- guidance: ``raspv_msgs/NavGuidance`` ↔ :class:`~raspv_nav.guidance.Guidance`.
"""
from __future__ import annotations

import array
import math

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Path as PathMsg
from raspv_msgs.msg import NavGuidance
from std_msgs.msg import Header

from raspv_common.conversions import array_to_point, matrix_to_pose, stamp_to_seconds, xyz_to_array
from raspv_nav.guidance import Guidance
from raspv_nav.motion import MapAlignment, planar_transform
from raspv_common.occupancy import OccupancyGrid


def path_to_msg(path: np.ndarray, header: Header) -> PathMsg:
    """(N, 2) or (N, 3) points in W → nav_msgs/Path."""
    msg = PathMsg(header=header)
    for p in np.asarray(path, dtype=float):
        ps = PoseStamped(header=header)
        ps.pose.position.x, ps.pose.position.y = float(p[0]), float(p[1])
        ps.pose.position.z = float(p[2]) if len(p) > 2 else 0.0
        ps.pose.orientation.w = 1.0
        msg.poses.append(ps)
    return msg


def path_from_msg(msg: PathMsg) -> np.ndarray:
    """nav_msgs/Path → (N, 3) points."""
    return np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in msg.poses],
                    dtype=float).reshape(-1, 3)


def costmap_to_msg(values: np.ndarray, grid: OccupancyGrid, alignment: MapAlignment, header: Header) -> OccupancyGridMsg:
    """int8 (rows, cols) occupancy values on ``grid`` (map frame M) → OccupancyGrid in W."""
    msg = OccupancyGridMsg(header=header)
    msg.info.map_load_time = header.stamp
    msg.info.resolution = float(grid.resolution)
    msg.info.height, msg.info.width = (int(v) for v in values.shape)
    msg.info.origin = matrix_to_pose(alignment.W_M @ planar_transform(grid.origin[0], grid.origin[1], 0.0))
    msg.data = array.array("b", np.ascontiguousarray(values, dtype=np.int8).tobytes())
    return msg


def guidance_to_msg(g: Guidance, header: Header) -> NavGuidance:
    msg = NavGuidance(header=header, has_path=g.has_path, goal_reached=g.goal_reached, reason=g.reason)
    if np.all(np.isfinite(g.position)):
        msg.position = array_to_point([g.position[0], g.position[1], 0.0])
    msg.heading = float(g.heading) if math.isfinite(g.heading) else 0.0
    msg.has_waypoint = g.next_waypoint is not None
    if g.next_waypoint is not None:
        msg.next_waypoint = array_to_point([g.next_waypoint[0], g.next_waypoint[1], 0.0])
    msg.distance_to_goal = float(g.distance_to_goal)
    msg.suggested.linear.x, msg.suggested.angular.z = float(g.linear), float(g.angular)
    msg.feasible = bool(g.feasible)
    msg.has_obstacle = g.nearest_obstacle is not None
    if g.nearest_obstacle is not None:
        msg.nearest_obstacle = array_to_point([g.nearest_obstacle[0], g.nearest_obstacle[1], 0.0])
    msg.nearest_obstacle_distance = float(g.nearest_obstacle_distance)
    return msg


def guidance_from_msg(msg: NavGuidance) -> Guidance:
    return Guidance(stamp_to_seconds(msg.header.stamp), bool(msg.has_path), bool(msg.goal_reached), msg.reason,
                    xyz_to_array(msg.position)[:2], float(msg.heading),
                    xyz_to_array(msg.next_waypoint)[:2] if msg.has_waypoint else None, float(msg.distance_to_goal),
                    float(msg.suggested.linear.x), float(msg.suggested.angular.z), bool(msg.feasible),
                    xyz_to_array(msg.nearest_obstacle)[:2] if msg.has_obstacle else None,
                    float(msg.nearest_obstacle_distance) if msg.has_obstacle else math.inf)
