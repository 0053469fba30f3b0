"""`planner` node: the navigation assistant in the graph.

Subscribes the robot pose (``/odom`` when a simulator publishes it, else ``/camera/pose``
projected on the floor), depth + camera info (obstacles). Publishes the global path
(``/nav/path``, world frame), a DWA velocity hint (``/nav/cmd_vel_hint``) and the building
costmap (``/nav/global_costmap``, latched).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from geometry_msgs.msg import PoseStamped, Twist
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMsg
from sensor_msgs.msg import CameraInfo, Image

from raspv_common import topics
from raspv_common.conversions import (pose_to_matrix, stamp_to_seconds)
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import COMMAND_QOS, LATCHED_QOS, SENSOR_QOS
from raspv_nav.assistant import NavigationAssistant
from raspv_nav.global_planner import PlannerConfig
from raspv_nav.local_planner import DWAConfig, obstacle_points
from raspv_nav.occupancy import MapFormatError, load_map
from raspv_nav.planner_params import PARAMS

CMD_VEL_HINT = "/nav/cmd_vel_hint"
GLOBAL_COSTMAP = "/nav/global_costmap"


def yaw_of(world_from_frame: np.ndarray, axis: int) -> float:
    """Heading in W of the frame's ``axis`` column projected on the floor."""
    d = world_from_frame[:3, axis]
    return math.atan2(d[1], d[0])


class PlannerNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("planner", PARAMS)
        p = self.params
        grid, self.world_goals = self._load_building(p)
        goal = self._goal_position(p)
        if isinstance(goal, str):
            raise ConfigurationError(goal)
        self.assistant = self._make_assistant(grid, p, goal)
        self.pose: tuple[float, float, float] | None = None
        self.velocity = (0.0, 0.0)
        self.odom_seen = False
        self.pub_path = self.create_publisher(PathMsg, topics.NAV_PATH, SENSOR_QOS)
        self.pub_hint = self.create_publisher(Twist, CMD_VEL_HINT, COMMAND_QOS)
        self.pub_costmap = self.create_publisher(OccupancyGridMsg, GLOBAL_COSTMAP, LATCHED_QOS)
        self.create_subscription(Odometry, topics.ODOM, self.on_odom, SENSOR_QOS)
        self.create_subscription(PoseStamped, topics.CAMERA_POSE, self.on_camera_pose, SENSOR_QOS)
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self.on_camera_info, SENSOR_QOS)
        self.create_subscription(Image, topics.DEPTH, self.on_depth, SENSOR_QOS)
        self.camera_pose: np.ndarray | None = None
        self._timers = []
        self._start_timers(p)
        self._goal_reached_logged = False
        self.publish_costmap(grid)
        self.get_logger().info(f"building map from {p['map'] or p['world']} ({grid.shape[1]}x{grid.shape[0]} cells at "
                               f"{grid.resolution} m), goal {p['goal_name'] or ''} {np.round(goal, 2).tolist()}")

    @staticmethod
    def _load_building(p: dict):
        """The building map and the named goals (empty for a map file)."""
        if bool(p["map"]) == bool(p["world"]):
            raise ConfigurationError("give exactly one of 'map' (map_server YAML) or 'world' (simulator world)")
        if p["map"]:
            try:
                return load_map(Path(p["map"])), {}
            except MapFormatError as exc:
                raise ConfigurationError(str(exc)) from None
        from raspv_sim.occupancy_export import world_occupancy
        from raspv_sim.simulator import SimConfig, Simulation
        from raspv_sim.world_spec import WorldFileError

        try:
            with Simulation(p["world"], SimConfig(width=16, height=12, renderer="tiny")) as sim:
                grid = world_occupancy(sim.world, 0.05, structure_only=True)
                goals = {g.name: np.array(g.position, dtype=float) for g in sim.spec.goals}
        except WorldFileError as exc:
            raise ConfigurationError(str(exc)) from None
        return grid, goals

    def _goal_position(self, p: dict):
        """Goal (x, y) from goal_name or goal; a string explains what is wrong."""
        if p["goal_name"]:
            if p["goal_name"] not in self.world_goals:
                known = ", ".join(sorted(self.world_goals)) or "none (goal names need 'world')"
                return f"goal_name {p['goal_name']!r} is not a goal of the world; goals: {known}"
            return self.world_goals[p["goal_name"]]
        if len(p["goal"]) != 2:
            return f"goal must be [x, y], got {p['goal']}"
        return np.array(p["goal"], dtype=float)

    @staticmethod
    def _make_assistant(grid, p: dict, goal: np.ndarray) -> NavigationAssistant:
        return NavigationAssistant(
            grid, goal,
            PlannerConfig(robot_radius=p["robot_radius"], inflation_radius=p["inflation_radius"]),
            DWAConfig(max_speed=p["max_speed"], robot_radius=p["robot_radius"]),
            goal_tolerance=p["goal_tolerance"], memory_s=p["obstacle_memory"])

    def _start_timers(self, p: dict) -> None:
        for t in self._timers:
            self.destroy_timer(t)
        self._timers = [self.create_timer(1.0 / p["replan_rate"], self.replan),
                        self.create_timer(1.0 / p["control_rate"], self.control)]

    def on_parameters(self, changes):
        merged = {**self.params, **changes}
        goal = self._goal_position(merged)
        if isinstance(goal, str):
            return goal
        self.assistant = self._make_assistant(self.assistant.grid, merged, goal)
        if "replan_rate" in changes or "control_rate" in changes:
            self._start_timers(merged)
        self._goal_reached_logged = False
        return None

    # -- inputs ------------------------------------------------------------------------------
    def now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_odom(self, msg: Odometry) -> None:
        T = pose_to_matrix(msg.pose.pose)
        self.odom_seen = True
        self.pose = (float(T[0, 3]), float(T[1, 3]), yaw_of(T, 0))
        self.velocity = (float(msg.twist.twist.linear.x), float(msg.twist.twist.angular.z))

    def on_camera_pose(self, msg: PoseStamped) -> None:
        self.camera_pose = pose_to_matrix(msg.pose)
        if not self.odom_seen:  # no body odometry: walk where the camera looks
            T = self.camera_pose
            self.pose = (float(T[0, 3]), float(T[1, 3]), yaw_of(T, 2))


    def on_depth(self, msg: Image) -> None:
        p = self.params
        if not p["use_camera_obstacles"] or self.intrinsics is None or self.camera_pose is None:
            return
        depth = self.read_depth(msg)
        if depth is None:
            return
        pts = obstacle_points(depth, self.intrinsics, self.camera_pose, p["obstacle_min_height"],
                              p["obstacle_max_height"], p["obstacle_range"])
        self.assistant.add_obstacles(pts, stamp_to_seconds(msg.header.stamp) or self.now_s())

    # -- outputs -----------------------------------------------------------------------------
    def replan(self) -> None:
        if self.pose is None:
            self.warn_throttled("pose", "waiting for /odom or /camera/pose")
            return
        status = self.assistant.replan(np.array(self.pose[:2]), self.now_s())
        if status.path is None:
            self.warn_throttled("nopath", f"no path to the goal: {status.reason}")
            return
        if status.goal_reached and not self._goal_reached_logged:
            self.get_logger().info(f"goal {np.round(self.assistant.goal, 2).tolist()} reached")
            self._goal_reached_logged = True
        msg = PathMsg(header=self.header("world"))
        for x, y in status.path:
            ps = PoseStamped(header=msg.header)
            ps.pose.position.x, ps.pose.position.y = float(x), float(y)
            msg.poses.append(ps)
        self.pub_path.publish(msg)

    def control(self) -> None:
        if self.pose is None:
            return
        res = self.assistant.velocity_hint(self.pose, self.velocity, self.now_s())
        hint = Twist()
        hint.linear.x, hint.angular.z = res.linear, res.angular
        self.pub_hint.publish(hint)

    def publish_costmap(self, grid) -> None:
        msg = OccupancyGridMsg(header=self.header("world"))
        msg.info.resolution = float(grid.resolution)
        msg.info.width, msg.info.height = int(grid.shape[1]), int(grid.shape[0])
        msg.info.origin.position.x, msg.info.origin.position.y = grid.origin
        msg.info.origin.orientation.w = 1.0
        msg.data = grid.cells.ravel().astype(np.int8).tolist()
        self.pub_costmap.publish(msg)


def main(argv=None) -> None:
    run_node(PlannerNode, argv)


if __name__ == "__main__":
    main()
