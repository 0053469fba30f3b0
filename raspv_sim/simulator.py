"""The virtual world in one object: a world file built in its own PyBullet client (DIRECT mode),
the BlindBot avatar, walking people, the RGB-D camera, collision events and goals (no rclpy).

    sim = Simulation("apartment")
    report = sim.step(0.05, linear=0.5, angular=0.0)   # s, m/s, rad/s
    frame = sim.render()                               # colour, depth [m], class ids, pose
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pybullet
from pybullet_utils.bullet_client import BulletClient

from raspv_common.intrinsics import CameraIntrinsics
from raspv_sim.avatar import Avatar, AvatarConfig, head_angles, head_quaternion
from raspv_sim.collision_events import CollisionEvent, CollisionMonitor, Touch
from raspv_sim.depth_sensor import DepthSensorConfig, DepthSensorModel
from raspv_sim.experiment_log import ExperimentLog, TrajectorySample
from raspv_sim.native_output import captured_native_output
from raspv_sim.sim_camera import RendererInfo, SimCamera, load_renderer
from raspv_sim.world_builder import BuiltWorld, build_world
from raspv_sim.world_spec import GoalSpec, WorldFileError, WorldSpec, display_path, load_world

DROP_NAME, DROP_CLASS = "edge", "drop"   # pseudo-object reported when the avatar stops at a drop


@dataclass(frozen=True)
class SimConfig:
    """Camera (px, deg, m), renderer ("auto", "egl" or "tiny"), avatar, optional depth realism.
    ``margin_deg`` widens the rendered image beyond ``width`` × ``height`` at ``hfov_deg`` by that
    much field of view on every side, at the same focal length (display-time reprojection in the
    spv node turns the view into it)."""

    width: int = 320
    height: int = 240
    hfov_deg: float = 60.0
    margin_deg: float = 0.0
    near: float = 0.05
    far: float = 8.0
    renderer: str = "auto"
    avatar: AvatarConfig = field(default_factory=AvatarConfig)
    depth_sensor: DepthSensorConfig | None = None
    collision_debounce: float = 0.5
    seed: int = 0
    textures: bool = False             # surface texture on static boxes (raspv_sim.surface_textures)

    def intrinsics(self) -> CameraIntrinsics:
        if not 0 < self.hfov_deg < 180:
            raise ValueError(f"horizontal field of view must be in (0, 180) degrees, got {self.hfov_deg}")
        camera = CameraIntrinsics.from_hfov(self.width, self.height, self.hfov_deg)
        return camera.with_margin(self.margin_deg) if self.margin_deg else camera


@dataclass
class SimFrame:
    """One camera frame at sim time ``t`` [s]: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 m
    (NaN: no reading), ``labels`` (H, W) uint8 class ids, ``world_from_camera`` 4×4 (optical frame)."""

    t: float
    rgb: np.ndarray
    depth: np.ndarray
    labels: np.ndarray | None          # None when rendered without labels
    world_from_camera: np.ndarray
    intrinsics: CameraIntrinsics


@dataclass
class StepReport:
    t: float
    distance: float                                    # m moved by the base in this step
    collisions: list[CollisionEvent] = field(default_factory=list)
    goals_reached: list[str] = field(default_factory=list)


class Simulation:
    def __init__(self, world: WorldSpec | str | Path, config: SimConfig | None = None):
        self.config = config or SimConfig()
        self.spec = world if isinstance(world, WorldSpec) else load_world(world)
        intrinsics = self.config.intrinsics()
        with captured_native_output():
            self.client = BulletClient(connection_mode=pybullet.DIRECT)
        try:
            # the EGL plugin only draws bodies created after it is loaded
            self.renderer: RendererInfo = load_renderer(self.client, self.config.renderer)
            self.world: BuiltWorld = build_world(self.client, self.spec, self.config.textures)
            s = self.spec
            self.avatar = Avatar(self.world, self.config.avatar, s.spawn_position[0], s.spawn_position[1],
                                 math.radians(s.spawn_yaw))
            problem = self.avatar.placement_problem()
            if problem:
                src = display_path(s.source) if s.source else s.name
                raise WorldFileError(f"{src}: spawn: the avatar at {list(s.spawn_position)} {problem}")
            self.camera = SimCamera(self.client, intrinsics, self.config.near, self.config.far, self.renderer,
                                    s.light_direction)
        except BaseException:
            self.close()
            raise
        self.monitor = CollisionMonitor(self.config.collision_debounce)
        self.depth_model = (DepthSensorModel(self.config.depth_sensor, intrinsics.fx, self.config.seed)
                            if self.config.depth_sensor is not None else None)
        self.t = 0.0
        self.linear = 0.0
        self.angular = 0.0
        self.goals_reached: dict[str, float] = {}
        self.trial_goals: tuple[GoalSpec, ...] = ()       # goals of the current trial (start_trial)
        self.people_t0 = 0.0                              # people walk from where they were at this time
        self.trial_t = 0.0                                # s since people_t0, summed step by step (the trial clock)
        self.log: ExperimentLog | None = None

    def start_trial(self, x: float, y: float, yaw: float, goals: tuple[GoalSpec, ...] = ()) -> None:
        """Start a trial (experiments): the avatar stands at (x, y) [m, W] facing ``yaw`` [rad] with
        the head straight ahead, people restart their walks from their initial places, the
        collision count and reached goals are cleared, and ``goals`` are checked besides the
        world's. Time keeps running (the clock never goes back). Raises ``ValueError`` when the
        avatar cannot stand there."""
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise ValueError(f"start pose must be finite numbers, got ({x}, {y}, {yaw})")
        old = (self.avatar.x, self.avatar.y, self.avatar.yaw)
        self.world.update_people(0.0)                     # people where they start, then check the pose
        self.avatar.teleport(x, y, yaw)
        problem = self.avatar.placement_problem()
        if problem:
            self.avatar.teleport(*old)
            self.world.update_people(self.trial_t)
            raise ValueError(f"the avatar at ({x:.2f}, {y:.2f}) {problem}")
        self.avatar.set_head((0.0, 0.0, 0.0, 1.0))
        self.avatar.path_length = 0.0
        self.linear = self.angular = 0.0
        self.people_t0, self.trial_t = self.t, 0.0
        self.monitor = CollisionMonitor(self.monitor.debounce_s)
        self.goals_reached = {}
        self.trial_goals = tuple(goals)
        if self.depth_model is not None:                  # the trial's sensor noise: from the seed and the start
            self.depth_model.start_trial(x, y, yaw)

    def start_log(self, log_dir: str | Path, rate: float = 10.0, extra: dict | None = None,
                  run_name: str | None = None) -> ExperimentLog:
        """Log this run from now on (trajectory at ``rate`` Hz, collisions, goals); see
        :mod:`raspv_sim.experiment_log`. Closed by :meth:`close`."""
        if self.log is not None:
            self.log.close()
        s, c = self.spec, self.config
        meta = {"world_file": str(s.source) if s.source else None, "description": s.description,
                "classes": list(s.classes), "spawn": {"position": list(s.spawn_position), "yaw_deg": s.spawn_yaw},
                "goals": [{"name": g.name, "position": list(g.position), "radius": g.radius}
                          for g in (*s.goals, *self.trial_goals)],
                "camera": {"width": c.width, "height": c.height, "hfov_deg": c.hfov_deg, "near": c.near, "far": c.far,
                           "renderer": self.renderer.name},
                "avatar": {k: getattr(c.avatar, k) for k in c.avatar.__dataclass_fields__},
                "depth_sensor": None if c.depth_sensor is None else
                {k: getattr(c.depth_sensor, k) for k in c.depth_sensor.__dataclass_fields__},
                **(extra or {})}
        self.log = ExperimentLog(log_dir, s.name, meta, rate, run_name, t0=self.t)
        self.log.sample(self.trajectory_sample(), force=True)
        return self.log

    def trajectory_sample(self) -> TrajectorySample:
        a = self.avatar
        roll, pitch, yaw = head_angles(a.head)
        cam = a.world_from_camera()[:3, 3]
        return TrajectorySample(self.t, a.x, a.y, a.z, a.yaw, roll, pitch, yaw, float(cam[0]), float(cam[1]),
                                float(cam[2]), self.linear, self.angular, a.path_length)

    @property
    def intrinsics(self) -> CameraIntrinsics:
        return self.camera.intrinsics

    @property
    def classes(self) -> tuple[str, ...]:
        return self.spec.classes

    def set_head(self, q) -> None:
        """Head orientation relative to the base, quaternion (x, y, z, w)."""
        self.avatar.set_head(q)

    def step(self, dt: float, linear: float = 0.0, angular: float = 0.0) -> StepReport:
        """Advance ``dt`` s: people walk, the avatar drives (m/s, rad/s, clamped to its limits)."""
        if not (dt >= 0 and math.isfinite(dt)):
            raise ValueError(f"time step must be a non-negative number of seconds, got {dt}")
        self.t += dt
        self.trial_t += dt          # summed from the trial's start, so the same in a graph and a quick trial
        self.world.update_people(self.trial_t)
        a = self.avatar.config
        self.linear = max(-a.max_linear, min(a.max_linear, float(linear)))
        self.angular = max(-a.max_angular, min(a.max_angular, float(angular)))
        result = self.avatar.move(self.linear, self.angular, dt)
        touches = []
        for contact in result.contacts:
            info = self.world.info(contact.uid)
            if info is not None:
                touches.append(Touch(info.name, info.cls, contact.position, contact.normal))
        if result.drop:
            yaw = self.avatar.yaw
            sign = 1.0 if self.linear >= 0 else -1.0
            touches.append(Touch(DROP_NAME, DROP_CLASS, (self.avatar.x, self.avatar.y, self.avatar.z),
                                 (-sign * math.cos(yaw), -sign * math.sin(yaw), 0.0)))
        report = StepReport(self.t, result.distance, self.monitor.update(self.t, touches, abs(self.linear), self.trial_t))
        for goal in (*self.spec.goals, *self.trial_goals):
            if goal.name not in self.goals_reached and math.hypot(self.avatar.x - goal.position[0],
                                                                   self.avatar.y - goal.position[1]) <= goal.radius:
                self.goals_reached[goal.name] = self.t
                report.goals_reached.append(goal.name)
        if self.log is not None:
            for event in report.collisions:
                self.log.collision(event)
            for name in report.goals_reached:
                self.log.goal(name, self.t)
            self.log.sample(self.trajectory_sample())
        return report

    def render(self, labels: bool = True) -> SimFrame:
        """The camera's view now (with the depth-sensor model applied when configured); without
        ``labels`` the frame's labels are None (a cheaper render unless the depth model needs them)."""
        T = self.avatar.world_from_camera()
        raw = self.camera.render(T, body=labels or self.depth_model is not None)
        if raw.body is None:
            return SimFrame(self.t, raw.rgb, raw.depth, None, T, self.camera.intrinsics)
        body = np.clip(raw.body + 1, 0, len(self.world.class_lut) - 1)
        depth = raw.depth
        if self.depth_model is not None:
            depth = self.depth_model.apply(depth, raw.rgb, self.world.specular_lut[body])
        return SimFrame(self.t, raw.rgb, depth, self.world.class_lut[body] if labels else None, T,
                        self.camera.intrinsics)

    def render_from(self, x: float, y: float, yaw: float, head_roll: float = 0.0, head_pitch: float = 0.0,
                    head_yaw: float = 0.0) -> SimFrame:
        """Put the avatar at (x, y) [m, world] facing ``yaw`` [rad], turn its head by
        roll/pitch/yaw [rad] relative to the base (pitch > 0 looks down), and render that view
        (no time passes, no collision check): views for figures, tests and replayed logs."""
        self.avatar.teleport(x, y, yaw)
        self.set_head(head_quaternion(head_roll, head_pitch, head_yaw))
        return self.render()

    def finish_log(self, plot: bool = True) -> tuple[dict, Path | None]:
        """End the log: last trajectory sample, ``summary.json`` and (``plot``) the top-down
        ``trajectory.png`` over the world's occupancy map. Returns (summary, png path)."""
        log = self.log
        if log is None:
            raise RuntimeError("no log was started")
        log.sample(self.trajectory_sample(), force=True)
        summary = log.close()
        self.log = None
        png = None
        if plot:
            from raspv_sim.occupancy_export import world_occupancy
            from raspv_sim.trajectory_plot import plot_run

            png = plot_run(log.dir, world_occupancy(self.world))
        return summary, png

    def close(self) -> None:
        """End the log (if any) and release the PyBullet client."""
        if getattr(self, "log", None) is not None and getattr(self, "client", None) is not None:
            self.finish_log()
        client = getattr(self, "client", None)
        if client is not None:
            with captured_native_output():
                try:
                    client.disconnect()
                except pybullet.error:
                    pass
            self.client = None

    def __enter__(self) -> "Simulation":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
