"""The navigation assistant of the paper (§III-F3, §IV-C), no rclpy.

A known building map gives the static layer of the costmap; depth frames (each with the camera
pose *at its stamp*) update the obstacle layer with marking and ray-cast clearing; A* replans
the global path from the subject; DWA proposes a collision-free velocity from the subject's
measured velocity; :class:`~raspv_nav.guidance.Guidance` is what the cues show.

Frames and time: poses and depth come in the world/odometry frame W of the pose source; the
building map and the goal are in the map frame M, placed in W by a :class:`MapAlignment`
(identity in the simulator, where W is the map). Paths, waypoints and obstacles go out in W,
where the spv node draws them with the same camera poses. Every time is a *data* stamp [s]
(message header, bag time when replaying); nothing reads a wall clock.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_nav.costmap import Costmap, CostmapConfig, CostmapState
from raspv_nav.global_planner import GlobalPlanner, NoPathError, PlanResult, path_length
from raspv_nav.guidance import Guidance, nearest_obstacle_ahead
from raspv_nav.local_planner import DWAConfig, DWAPlanner, DWAResult, grid_clearance, lookahead_point
from raspv_nav.motion import MapAlignment
from raspv_nav.obstacle_layer import DepthObservation, ObstacleLayerConfig
from raspv_common.occupancy import OccupancyGrid


@dataclass
class AssistantConfig:
    costmap: CostmapConfig = field(default_factory=CostmapConfig)
    obstacles: ObstacleLayerConfig = field(default_factory=ObstacleLayerConfig)
    dwa: DWAConfig = field(default_factory=DWAConfig)
    goal_tolerance: float = 0.4           # [m] the goal counts as reached within this
    max_relocation: float = 1.5           # [m] start/goal moved out of the inflated zone up to this
    proximity_range: float = 1.5          # [m] obstacle proximity cue range
    proximity_cone_deg: float = 60.0      # full width of the cone ahead searched for it


@dataclass
class NavigationStatus:
    stamp: float                          # data time of the pose planned from [s]
    path: np.ndarray | None               # (N, 2) W, from the subject to the goal; None without one
    reason: str                           # why there is no path ("" when there is one)
    goal_reached: bool
    distance_to_goal: float               # straight line [m]
    path_length: float                    # [m], nan without path
    plan: PlanResult | None = None


class NavigationAssistant:
    def __init__(self, grid: OccupancyGrid, goal, config: AssistantConfig | None = None,
                 alignment: MapAlignment | None = None) -> None:
        self.config = config or AssistantConfig()
        self.alignment = alignment or MapAlignment()
        self.grid = grid
        self.costmap = Costmap(grid, self.config.costmap, self.config.obstacles)
        self.planner = GlobalPlanner(self.costmap, max_relocation=self.config.max_relocation)
        self.dwa = DWAPlanner(self.config.dwa)
        self.goal = np.asarray(goal, dtype=float)[:2]            # M
        self.subject: tuple[float, float, float, float] | None = None   # (stamp, x, y, yaw) in M
        self.path_map: np.ndarray | None = None                  # (N, 2) M
        self.status = NavigationStatus(math.nan, None, "not planned yet", False, math.inf, math.nan)
        self.last_command: DWAResult | None = None

    # -- inputs (W) ------------------------------------------------------------------------------
    @property
    def now(self) -> float | None:
        """The newest data stamp seen [s]."""
        stamps = [s for s in (self.costmap.obstacle_layer.stamp, self.subject[0] if self.subject else None)
                  if s is not None]
        return max(stamps) if stamps else None

    def set_subject(self, stamp: float, x: float, y: float, yaw: float) -> None:
        """The subject's floor position and walking direction in W at data time ``stamp``."""
        xy = self.alignment.points_to_map([[x, y]])[0]
        yaw_m = yaw + math.atan2(self.alignment.M_W[1, 0], self.alignment.M_W[0, 0])
        if self.subject is not None and stamp < self.subject[0] - self.config.obstacles.reset_on_jump_s:
            self.costmap.obstacle_layer.clear()                   # time went back: a bag looped
        self.subject = (stamp, float(xy[0]), float(xy[1]), yaw_m)

    def add_depth(self, depth: np.ndarray, intrinsics: CameraIntrinsics, world_from_camera: np.ndarray,
                  stamp: float) -> DepthObservation:
        """A depth frame (H, W) [m] with the camera pose W ← C *at its stamp* [s]."""
        return self.costmap.obstacle_layer.add_depth(depth, intrinsics, self.alignment.pose_to_map(world_from_camera),
                                                     stamp)

    # -- planning ------------------------------------------------------------------------------
    def costmap_state(self) -> CostmapState:
        return self.costmap.update(self.now)

    def replan(self) -> NavigationStatus:
        """Global path from the subject's newest pose to the goal on the current costmap."""
        if self.subject is None:
            self.status = NavigationStatus(math.nan, None, "no pose yet", False, math.inf, math.nan)
            return self.status
        stamp, x, y, _ = self.subject
        position = np.array([x, y])
        dist = float(np.linalg.norm(self.goal - position))
        if dist <= self.config.goal_tolerance:
            self.path_map = np.stack([position, self.goal])
            self.status = NavigationStatus(stamp, self.alignment.points_to_world(self.path_map), "", True, dist, dist)
            return self.status
        state = self.costmap_state()
        try:
            plan = self.planner.plan(position, self.goal, state)
        except NoPathError as exc:
            self.path_map = None
            self.status = NavigationStatus(stamp, None, str(exc), False, dist, math.nan)
            return self.status
        self.path_map = plan.path
        self.status = NavigationStatus(stamp, self.alignment.points_to_world(plan.path), "", False, dist,
                                       path_length(plan.path), plan)
        return self.status

    def velocity_hint(self, velocity=(0.0, 0.0)) -> DWAResult:
        """DWA command (base frame: v forward, w left) from the subject's newest pose and measured
        ``velocity`` (v, w) along the current path; trajectory and target in W."""
        if self.subject is None or self.path_map is None:
            result = DWAResult(0.0, 0.0, np.empty((0, 2)), False)
        else:
            _, x, y, yaw = self.subject
            if np.linalg.norm(self.goal - [x, y]) <= self.config.goal_tolerance:
                result = DWAResult(0.0, 0.0, np.empty((0, 2)), True, self.goal.copy())
            else:
                clearance = grid_clearance(self.costmap.state, self.grid)
                result = self.dwa.command((x, y, yaw), velocity, self.path_map, clearance)
        self.last_command = result
        return DWAResult(result.linear, result.angular, self.alignment.points_to_world(result.trajectory)
                         if len(result.trajectory) else result.trajectory, result.feasible,
                         None if result.target is None else self.alignment.points_to_world(result.target)[0])

    def guidance(self, command: DWAResult | None = None) -> Guidance:
        """The cues for the subject's newest pose (W), with the last DWA ``command``."""
        command = command or self.last_command or DWAResult(0.0, 0.0, np.empty((0, 2)), False)
        s = self.status
        if self.subject is None:
            return Guidance(math.nan, False, False, "no pose yet", np.full(2, np.nan), math.nan, None, math.inf,
                            0.0, 0.0, False, None, math.inf)
        stamp, x, y, yaw = self.subject
        position = np.array([x, y])
        waypoint = None
        remaining = float(np.linalg.norm(self.goal - position))
        if self.path_map is not None and len(self.path_map) >= 2:
            waypoint = lookahead_point(self.path_map, position, self.config.dwa.lookahead)
            remaining = path_length(self.path_map)
        state = self.costmap.state
        obstacle, obstacle_dist = nearest_obstacle_ahead(state.obstacles, self.grid, position, yaw,
                                                         self.config.proximity_range, self.config.proximity_cone_deg)
        to_world = self.alignment.points_to_world
        return Guidance(stamp, self.path_map is not None, s.goal_reached, s.reason, to_world(position)[0],
                        self.alignment.yaw_to_world(yaw), None if waypoint is None else to_world(waypoint)[0],
                        remaining, command.linear, command.angular, command.feasible,
                        None if obstacle is None else to_world(obstacle)[0], obstacle_dist)


def assistant_config(p: dict) -> AssistantConfig:
    """The core's configuration from the node's parameters (raises ValueError)."""
    return AssistantConfig(
        costmap=CostmapConfig(robot_radius=p["robot_radius"], inflation_radius=p["inflation_radius"],
                              cost_weight=p["cost_weight"]),
        obstacles=ObstacleLayerConfig(min_height=p["obstacle_min_height"], max_height=p["obstacle_max_height"],
                                      max_range=p["obstacle_range"], decay_s=p["obstacle_memory"]),
        dwa=DWAConfig(max_speed=p["max_speed"], robot_radius=p["robot_radius"]),
        goal_tolerance=p["goal_tolerance"], max_relocation=p["max_relocation"], proximity_range=p["proximity_range"])
