"""`planner` node: the navigation assistant (:mod:`raspv_nav.assistant`) in the graph.

Subscribes the subject's pose (``/odom``, the base, when a simulator publishes it; else
``/camera/pose`` with the camera's heading — see ``pose_source``), camera info and depth. Each
depth frame updates the obstacle layer with the camera pose *at its stamp* (a
:class:`~raspv_common.pose_buffer.PoseBuffer`; a frame newer than the newest pose waits for
it). Publishes, in the frame of the poses (``world``):

- ``/nav/path`` (nav_msgs/Path, stamped with the pose it was planned from; empty when there is
  no path, so no stale path stays on screen) at ``replan_rate``;
- ``/nav/cmd_vel_hint`` (Twist, base frame) and ``/nav/guidance`` (raspv_msgs/NavGuidance) at
  ``control_rate``: the DWA suggestion from the measured velocity (``/odom`` twist, or the
  velocity of successive poses);
- ``/nav/global_costmap`` (latched: the inflated static layer), ``/nav/costmap`` (the inflated
  static + obstacle layers) and ``/nav/obstacle_layer`` (the live layer) as
  nav_msgs/OccupancyGrid at ``costmap_rate``.

All times are message stamps, so a replayed bag works with bag time.

With ``lockstep`` (scripted subjects, :mod:`raspv_sim.lockstep`) there are no timers: frame k of
the simulator is handled once its depth, camera pose, odometry and the ``/spv/frame`` shown from
it are in — obstacles, a replan when 1/``replan_rate`` s of frame time have passed, the velocity
hint, the costmaps — and then answered on ``/sim/lockstep``, so the world steps only after the
path planned from frame k is out and every run shows the same path on the same frame.
"""
from __future__ import annotations

import math
import statistics
import time
from collections import deque
from pathlib import Path

import numpy as np
from geometry_msgs.msg import PoseStamped, Twist, TwistStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMsg
from raspv_msgs.msg import NavGuidance, PhospheneFrame
from sensor_msgs.msg import CameraInfo, Image

from raspv_common import frames, topics
from raspv_common.conversions import pose_to_matrix, stamp_to_seconds
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.pose_buffer import PoseBuffer
from raspv_common.qos import COMMAND_QOS, LATCHED_QOS, SENSOR_QOS
from raspv_nav.assistant import NavigationAssistant, assistant_config
from raspv_nav.motion import MapAlignment, VelocityEstimator, planar_pose
from raspv_nav.nav_msg import costmap_to_msg, guidance_to_msg, path_to_msg
from raspv_common.occupancy import MapFormatError, load_map
from raspv_nav.planner_params import PARAMS


class PlannerNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("planner", PARAMS)
        p = self.params
        grid, self.world_goals = self._load_building(p)
        goal = self._goal_position(p)
        if isinstance(goal, str):
            raise ConfigurationError(goal)
        x, y, yaw_deg = self._map_from_odom(p)
        try:
            self.assistant = NavigationAssistant(grid, goal, assistant_config(p),
                                                 MapAlignment((x, y, math.radians(yaw_deg))))
        except ValueError as exc:
            raise ConfigurationError(str(exc)) from None
        self.camera_poses = PoseBuffer(max_age_s=5.0, max_extrapolation_s=0.1)
        self.velocity_estimator = VelocityEstimator()
        self.odom_velocity: tuple[float, float] | None = None
        self.frame_id = frames.MAP       # the frame of /camera/pose; the sim's /odom is ground truth (odom = map)
        self.pending_depth: tuple[float, np.ndarray] | None = None     # waits for a pose at its stamp
        self._goal_reached_logged = False
        self.timings: dict[str, deque] = {k: deque(maxlen=5000) for k in ("replan", "depth", "control")}
        self.pub_path = self.create_publisher(PathMsg, topics.NAV_PATH, SENSOR_QOS)
        self.pub_hint = self.create_publisher(Twist, topics.NAV_CMD_VEL_HINT, COMMAND_QOS)
        self.pub_guidance = self.create_publisher(NavGuidance, topics.NAV_GUIDANCE, SENSOR_QOS)
        self.pub_global = self.create_publisher(OccupancyGridMsg, topics.NAV_GLOBAL_COSTMAP, LATCHED_QOS)
        self.pub_costmap = self.create_publisher(OccupancyGridMsg, topics.NAV_COSTMAP, SENSOR_QOS)
        self.pub_layer = self.create_publisher(OccupancyGridMsg, topics.NAV_OBSTACLE_LAYER, SENSOR_QOS)
        if p["pose_source"] != "camera":
            self.create_subscription(Odometry, topics.ODOM, self.on_odom, SENSOR_QOS)
        self.create_subscription(PoseStamped, topics.CAMERA_POSE, self.on_camera_pose, SENSOR_QOS)
        self.create_subscription(CameraInfo, topics.CAMERA_INFO, self.on_camera_info, SENSOR_QOS)
        self.create_subscription(Image, topics.DEPTH, self.on_depth, SENSOR_QOS)
        self._timers: list = []
        self.lockstep = bool(p["lockstep"])
        self._lock_in: dict[str, float] = {"odom": -1.0, "spv": -1.0}   # newest stamp of each input [s]
        self._lock_depth: tuple[float, np.ndarray | None] | None = None  # the frame waiting to be handled
        self._lock_last: dict[str, float] = {"replan": -1e9, "control": -1e9, "costmap": -1e9}
        if self.lockstep:
            self.pub_lockstep = self.create_publisher(TwistStamped, topics.SIM_LOCKSTEP, COMMAND_QOS)
            self.create_subscription(PhospheneFrame, topics.SPV_FRAME, self.on_spv_frame, SENSOR_QOS)
        else:
            self._start_timers(p)
        self.publish_global_costmap()
        self.get_logger().info(f"building map from {p['map'] or p['world']} ({grid.shape[1]}x{grid.shape[0]} cells at "
                               f"{grid.resolution} m), goal {p['goal_name'] or ''} {np.round(goal, 2).tolist()}, "
                               f"map_from_odom {[round(x, 3), round(y, 3), round(yaw_deg, 2)]}")

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

    def _map_from_odom(self, p: dict) -> tuple[float, float, float]:
        """(x, y [m], yaw [deg]) of the pose frame on the building map: ``map_from_odom`` when set,
        else the alignment stored with ``slam_map``, else identity."""
        if len(p["map_from_odom"]) != 3:
            raise ConfigurationError(f"map_from_odom must be [x, y, yaw_deg], got {p['map_from_odom']}")
        manual = tuple(float(v) for v in p["map_from_odom"])
        if not p["slam_map"]:
            return manual
        if any(manual):
            self.get_logger().info(f"map_from_odom {list(manual)} overrides the alignment stored with {p['slam_map']}")
            return manual
        from raspv_common.slam_map_files import SlamMapError, building_map_sha256, load_alignment

        try:
            stored = load_alignment(p["slam_map"])
        except SlamMapError as exc:
            raise ConfigurationError(str(exc)) from None
        if p["map"] and stored.building_sha256 and building_map_sha256(p["map"]) != stored.building_sha256:
            self.get_logger().warning(f"{p['slam_map']} was aligned to {stored.building_map}, not to {p['map']} "
                                      "(the files differ): align it again with raspv slam align")
        self.get_logger().info(f"map frame placed on the building map by {p['slam_map']}'s alignment "
                               f"(score {stored.score:.2f}, {stored.matched:.0%} of its walls on the building's)")
        return stored.x, stored.y, stored.yaw_deg

    def _goal_position(self, p: dict):
        """Goal (x, y) in the map frame from goal_name or goal; a string explains what is wrong."""
        if p["goal_name"]:
            if p["goal_name"] not in self.world_goals:
                known = ", ".join(sorted(self.world_goals)) or "none (goal names need 'world')"
                return f"goal_name {p['goal_name']!r} is not a goal of the world; goals: {known}"
            return self.world_goals[p["goal_name"]]
        if len(p["goal"]) != 2:
            return f"goal must be [x, y], got {p['goal']}"
        return np.array(p["goal"], dtype=float)

    def _start_timers(self, p: dict) -> None:
        for t in self._timers:
            self.destroy_timer(t)
        self._timers = [self.create_timer(1.0 / p["replan_rate"], self.replan),
                        self.create_timer(1.0 / p["control_rate"], self.control)]
        if p["costmap_rate"] > 0:
            self._timers.append(self.create_timer(1.0 / p["costmap_rate"], self.publish_costmaps))

    def on_parameters(self, changes):
        merged = {**self.params, **changes}
        goal = self._goal_position(merged)
        if isinstance(goal, str):
            return goal
        self.assistant.goal = np.asarray(goal, dtype=float)[:2]
        self.assistant.config.max_relocation = merged["max_relocation"]
        self.assistant.planner.max_relocation = merged["max_relocation"]
        if {"replan_rate", "control_rate", "costmap_rate"} & set(changes) and not self.lockstep:
            self._start_timers(merged)
        if "goal" in changes or "goal_name" in changes:
            self._goal_reached_logged = False
        return None

    # -- inputs ------------------------------------------------------------------------------
    def _use_odom(self) -> bool:
        return self.params["pose_source"] == "odom" or (self.params["pose_source"] == "auto"
                                                         and self.odom_velocity is not None)

    def on_odom(self, msg: Odometry) -> None:
        try:
            T = pose_to_matrix(msg.pose.pose)
            if not np.all(np.isfinite(T)):
                raise ValueError("the pose is not finite")
        except ValueError as exc:
            self.warn_throttled("odom", f"ignoring {topics.ODOM}: {exc}")
            return
        v, w = msg.twist.twist.linear.x, msg.twist.twist.angular.z
        self.odom_velocity = (float(v), float(w)) if math.isfinite(v) and math.isfinite(w) else (0.0, 0.0)
        self.assistant.set_subject(stamp_to_seconds(msg.header.stamp), *planar_pose(T, axis=0))
        if self.lockstep:
            self._lock_in["odom"] = max(self._lock_in["odom"], stamp_to_seconds(msg.header.stamp))
            self._lockstep_frame()

    def on_camera_pose(self, msg: PoseStamped) -> None:
        stamp = stamp_to_seconds(msg.header.stamp)
        try:
            T = pose_to_matrix(msg.pose)
            self.camera_poses.add(stamp, T)
        except ValueError as exc:
            self.warn_throttled("pose", f"ignoring {topics.CAMERA_POSE}: {exc}")
            return
        if not self._use_odom():           # no body odometry: the subject walks where the camera looks
            x, y, yaw = planar_pose(T, axis=2)
            self.velocity_estimator.add(stamp, x, y, yaw)
            self.assistant.set_subject(stamp, x, y, yaw)
        if self.lockstep:
            self._lockstep_frame()
            return
        if self.pending_depth is not None and self.pending_depth[0] <= stamp:
            pending, self.pending_depth = self.pending_depth, None
            self._add_depth(*pending)

    def on_depth(self, msg: Image) -> None:
        if self.lockstep:
            self._lock_depth = (stamp_to_seconds(msg.header.stamp), msg)
            self._lockstep_frame()
            return
        if not self.params["use_camera_obstacles"] or self.intrinsics is None:
            return
        depth = self.read_depth(msg)
        if depth is None:
            return
        stamp = stamp_to_seconds(msg.header.stamp)
        latest = self.camera_poses.latest()
        if latest is not None and stamp > latest.stamp:
            self.pending_depth = (stamp, depth)          # the pose of this frame is on its way
            return
        self._add_depth(stamp, depth)

    def _add_depth(self, stamp: float, depth: np.ndarray) -> None:
        pose = self.camera_poses.lookup_or_none(stamp)
        if pose is None:
            self.warn_throttled("depth-pose", f"no camera pose at the depth stamp {stamp:.3f} s on "
                                              f"{topics.CAMERA_POSE}; its obstacles are not used")
            return
        t0 = time.perf_counter()
        self.assistant.add_depth(depth, self.intrinsics, pose, stamp)
        self.timings["depth"].append(1e3 * (time.perf_counter() - t0))

    # -- lockstep ----------------------------------------------------------------------------
    def on_spv_frame(self, msg: PhospheneFrame) -> None:
        self._lock_in["spv"] = max(self._lock_in["spv"], stamp_to_seconds(msg.source_stamp))
        self._lockstep_frame()

    def on_camera_info(self, msg: CameraInfo) -> None:
        super().on_camera_info(msg)
        if self.lockstep:
            self._lockstep_frame()

    def _lockstep_frame(self) -> None:
        """Handle the waiting frame once all of it is in (see the module docstring), then answer it."""
        if self._lock_depth is None:
            return
        stamp, msg = self._lock_depth
        latest = self.camera_poses.latest()
        need_odom = self.params["pose_source"] != "camera"
        if (latest is None or latest.stamp < stamp - 1e-6 or self._lock_in["spv"] < stamp - 1e-6
                or (need_odom and self._lock_in["odom"] < stamp - 1e-6)
                or (self.params["use_camera_obstacles"] and self.intrinsics is None)):
            return
        self._lock_depth = None
        if self.params["use_camera_obstacles"]:
            depth = self.read_depth(msg)
            if depth is not None:
                self._add_depth(stamp, depth)
        p, last = self.params, self._lock_last
        for name, rate, action in (("replan", p["replan_rate"], self.replan), ("control", p["control_rate"], self.control),
                                   ("costmap", p["costmap_rate"], self.publish_costmaps)):
            if rate > 0 and stamp - last[name] >= 1.0 / rate - 1e-6:
                last[name] = stamp
                action()
        answer = TwistStamped()
        answer.header.stamp = msg.header.stamp
        answer.header.frame_id = "planner"
        self.pub_lockstep.publish(answer)

    # -- outputs -----------------------------------------------------------------------------
    def replan(self) -> None:
        t0 = time.perf_counter()
        status = self.assistant.replan()
        if status.plan is not None:
            self.timings["replan"].append(1e3 * (time.perf_counter() - t0))
        if self.assistant.subject is None:
            self.warn_throttled("pose", f"waiting for {topics.ODOM} or {topics.CAMERA_POSE}")
            return
        header = self.header(self.frame_id, status.stamp)
        if status.path is None:
            self.warn_throttled("nopath", f"no path to the goal: {status.reason}")
            self.pub_path.publish(PathMsg(header=header))       # nothing stale stays on screen
            return
        if status.goal_reached and not self._goal_reached_logged:
            self.get_logger().info(f"goal {np.round(self.assistant.goal, 2).tolist()} reached")
            self._goal_reached_logged = True
        self.pub_path.publish(path_to_msg(status.path, header))

    def control(self) -> None:
        if self.assistant.subject is None:
            return
        velocity = self.odom_velocity if self._use_odom() else self.velocity_estimator.velocity()
        t0 = time.perf_counter()
        self.assistant.costmap_state()
        result = self.assistant.velocity_hint(velocity)
        self.timings["control"].append(1e3 * (time.perf_counter() - t0))
        hint = Twist()
        hint.linear.x, hint.angular.z = result.linear, result.angular
        self.pub_hint.publish(hint)
        guidance = self.assistant.guidance()
        self.pub_guidance.publish(guidance_to_msg(guidance, self.header(self.frame_id, guidance.stamp)))

    def publish_global_costmap(self) -> None:
        a = self.assistant
        self.pub_global.publish(costmap_to_msg(a.costmap.static.occupancy_values(), a.grid, a.alignment,
                                               self.header(self.frame_id)))

    def publish_costmaps(self) -> None:
        a = self.assistant
        stamp = a.now
        header = self.header(self.frame_id, stamp)
        self.pub_costmap.publish(costmap_to_msg(a.costmap.state.occupancy_values(), a.grid, a.alignment, header))
        self.pub_layer.publish(costmap_to_msg(a.costmap.obstacle_layer.occupancy_values(stamp), a.grid,
                                              a.alignment, header))

    def close(self) -> None:
        # rclpy's context may already be shut down here: report with print, not the ROS logger
        parts = []
        for name, what in (("replan", "replans (A*)"), ("depth", "depth frames into the costmap"),
                           ("control", "control steps (inflation + DWA)")):
            v = sorted(getattr(self, "timings", {}).get(name, ()))
            if v:
                parts.append(f"{len(v)} {what} median {statistics.median(v):.1f} ms, "
                             f"p95 {v[min(len(v) - 1, int(0.95 * (len(v) - 1)))]:.1f} ms")
        if parts:
            print("planner: " + "; ".join(parts), flush=True)


def main(argv=None) -> None:
    run_node(PlannerNode, argv, priority="perception")


if __name__ == "__main__":
    main()
