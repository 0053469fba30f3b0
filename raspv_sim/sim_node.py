"""`sim` node: the virtual world as an RGB-D source (same topics as a real camera) plus ground truth.

Publishes colour (rgb8), depth (32FC1 m), camera info, ``/camera/pose`` (map ← camera optical),
``/odom`` (base_link in odom), the tf tree of ground truth (``/tf_static``: map → odom identity,
head → camera_link → optical; ``/tf`` per frame: odom → base_link, base_link → head), ``/sim/labels`` (mono8 class ids), ``/sim/classes`` (latched
std_msgs/String, JSON ``{"world": name, "classes": [name of id 0, id 1, ...]}``) and
``/sim/collisions`` (raspv_msgs/CollisionEvent). Subscribes ``/cmd_vel`` (Twist, base frame) and
``/head/orientation`` (QuaternionStamped, head relative to the base; identity looks ahead).

Experiments: ``/clock`` carries the simulation time; the services ``/sim/start_trial`` and
``/sim/end_trial`` (raspv_msgs/srv) put the avatar at a start pose and log one trial; with
``step_mode: lockstep`` the world steps when a controller answers the last frame on
``/sim/lockstep`` (:mod:`raspv_sim.lockstep`), stamped in sim time; ``paused`` holds the world.
With ``lockstep_hold`` the world steps only while a trial runs: from ``/sim/start_trial`` with a
log until the trial's goal region is reached or its ``time_limit`` has passed, so every trial
ends on the same frame and nothing happens between trials (no frames, only ``/clock`` and
``/odom`` repeated twice a second so late subscribers see where the world holds).
"""
from __future__ import annotations

import dataclasses
import json
import math
import threading
import time

import numpy as np
from geometry_msgs.msg import Point, PoseStamped, QuaternionStamped, Twist, TwistStamped, Vector3
from nav_msgs.msg import Odometry
from raspv_msgs.msg import CollisionEvent as CollisionEventMsg
from raspv_msgs.srv import EndTrial, StartTrial
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header, String

from raspv_common import frames, topics
from raspv_common.conversions import array_to_image, intrinsics_to_camera_info, matrix_to_pose, stamp_to_seconds
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import COMMAND_QOS, EVENT_QOS, LATCHED_QOS, SENSOR_QOS
from raspv_common.tf_messages import StaticTfBroadcaster, TfBroadcaster
from raspv_sim.avatar import AvatarConfig
from raspv_sim.collision_events import CollisionEvent
from raspv_sim.depth_sensor import DepthSensorModel, sensor_config_from_params
from raspv_sim.lockstep import Lockstep
from raspv_sim.sim_node_gaze import SimGazeLog
from raspv_sim.sim_params import PARAMS
from raspv_sim.simulator import SimConfig, Simulation
from raspv_sim.world_spec import GoalSpec, WorldFileError

MAX_STEP_S = 0.2               # a stalled tick never moves the avatar more than this much time

_AVATAR_PARAMS = {"eye_height": "eye_height", "max_linear": "max_linear", "max_angular": "max_angular",
                  "slide": "slide"}


def _import_run_plotting() -> None:
    """Import what :meth:`Simulation.finish_log` plots with (matplotlib: seconds on a loaded machine)."""
    import raspv_sim.occupancy_export  # noqa: F401
    import raspv_sim.trajectory_plot  # noqa: F401


depth_sensor_config = sensor_config_from_params


def sim_config(p: dict) -> SimConfig:
    avatar = AvatarConfig(body_radius=p["body_radius"], eye_height=p["eye_height"], max_linear=p["max_linear"],
                          max_angular=p["max_angular"], max_step=p["max_step"], slide=p["slide"])
    return SimConfig(width=p["width"], height=p["height"], hfov_deg=p["hfov_deg"], margin_deg=p["margin_deg"],
                     near=p["near"], far=p["far"],
                     renderer=p["renderer"], avatar=avatar, depth_sensor=depth_sensor_config(p),
                     collision_debounce=p["collision_debounce"], seed=p["seed"], textures=p["textures"])


class SimNode(SimGazeLog, RaspvNode):
    def __init__(self) -> None:
        super().__init__("sim", PARAMS)
        self._plotting_import: threading.Thread | None = None
        p = self.params
        if not p["far"] > p["near"]:
            raise ConfigurationError(f"'far' ({p['far']} m) must be larger than 'near' ({p['near']} m)")
        try:
            config = sim_config(p)
            self.sim = Simulation(p["world"], config)
        except WorldFileError as exc:
            raise ConfigurationError(str(exc)) from None
        except (ValueError, RuntimeError) as exc:
            raise ConfigurationError(str(exc)) from None
        if p["log_dir"]:
            try:
                log = self.sim.start_log(p["log_dir"], p["log_rate"])
            except OSError as exc:
                self.sim.close()
                raise ConfigurationError(f"cannot write logs to '{p['log_dir']}': {exc.strerror}") from None
            self.get_logger().info(f"logging the run to {log.dir}")
            # the run's plot is drawn at shutdown: import matplotlib now, not within the stop's grace.
            # Not a daemon, and joined in close(): a daemon thread still importing a C++ extension
            # when the interpreter exits is ended by pthread_exit inside C++ code, which aborts the
            # process ("terminate called without an active exception", exit -6: demo test, 7 Dec)
            self._plotting_import = threading.Thread(target=_import_run_plotting, name="import-plotting")
            self._plotting_import.start()
        self.camera_info = intrinsics_to_camera_info(self.sim.intrinsics)
        self.pub_color = self.create_publisher(Image, topics.COLOR, SENSOR_QOS)
        self.pub_depth = self.create_publisher(Image, topics.DEPTH, SENSOR_QOS)
        self.pub_info = self.create_publisher(CameraInfo, topics.CAMERA_INFO, SENSOR_QOS)
        self.pub_pose = self.create_publisher(PoseStamped, topics.CAMERA_POSE, SENSOR_QOS)
        self.pub_odom = self.create_publisher(Odometry, topics.ODOM, SENSOR_QOS)
        self.pub_labels = self.create_publisher(Image, topics.SIM_LABELS, SENSOR_QOS)
        self.pub_collisions = self.create_publisher(CollisionEventMsg, topics.SIM_COLLISIONS, EVENT_QOS)
        self.pub_classes = self.create_publisher(String, topics.SIM_CLASSES, LATCHED_QOS)
        self.pub_classes.publish(String(data=json.dumps({"world": self.sim.spec.name, "classes": list(self.sim.classes)})))
        # ground truth: map = odom (no drift); the head turns under base_link; the eye and the
        # optical axes are fixed to the head
        self.tf = TfBroadcaster(self)
        StaticTfBroadcaster(self).send([
            (frames.MAP, frames.ODOM, np.eye(4)),
            (frames.HEAD, frames.CAMERA_LINK, self.sim.avatar.head_from_camera_link()),
            (frames.CAMERA_LINK, p["frame_id"], frames.LINK_FROM_OPTICAL)])
        self._commands = [self.create_subscription(Twist, topics.CMD_VEL, self.on_cmd_vel, COMMAND_QOS),
                          self.create_subscription(QuaternionStamped, topics.HEAD_ORIENTATION, self.on_head, COMMAND_QOS)]
        self._setup_gaze_log()              # every eye-gaze sample into the run's log (gaze.csv), while one is written
        self.cmd = (0.0, 0.0)
        self.cmd_time = -math.inf
        self.head: tuple[float, float, float, float] | None = None     # the last head orientation received
        self.last_tick: float | None = None
        self.timings = {"step": 0.0, "render": 0.0, "publish": 0.0, "frames": 0}
        self.pub_clock = self.create_publisher(Clock, topics.CLOCK, COMMAND_QOS)
        self.create_service(StartTrial, topics.SIM_START_TRIAL, self.on_start_trial)
        self.create_service(EndTrial, topics.SIM_END_TRIAL, self.on_end_trial)
        self.lockstep: Lockstep | None = None
        self.trial_end: float | None = None        # lockstep_hold: sim time at which the running trial holds
        self._held_repeat = 0.0                   # wall time [s] /clock and /odom were last repeated while held
        if p["step_mode"] == "lockstep":
            self.lockstep = Lockstep(p["lockstep_timeout"], frozenset(x for x in p["lockstep_participants"] if x))
            self.lockstep.hold = bool(p["lockstep_hold"])
            self.lockstep.strict = bool(p["lockstep_hold"])     # a scripted session waits for every answer
            # every answer counts: the subject and the planner answer each frame on one topic, and with
            # a queue of one the later answer replaced the earlier when both came while this node was busy
            self.create_subscription(TwistStamped, topics.SIM_LOCKSTEP, self.on_lockstep, EVENT_QOS)
            self.create_timer(0.02, self.lockstep_poll)
        else:
            self.create_timer(1.0 / p["rate"], self.tick)
        s, K = self.sim.spec, self.sim.intrinsics
        margin = f" + {p['margin_deg']:g}° margin = {K.width}x{K.height} {K.hfov_deg:.0f}°" if p["margin_deg"] else ""
        self.get_logger().info(
            f"world '{s.name}' ({s.source}), renderer: {self.sim.renderer.description}; camera {p['width']}x{p['height']} "
            f"{p['hfov_deg']:g}°{margin} at {p['rate']:g} Hz, eye height {p['eye_height']} m; depth noise "
            f"{'on' if p['depth_noise'] else 'off'}" + ("; lockstep stepping" if self.lockstep else ""))

    # -- inputs ---------------------------------------------------------------------------------
    def on_cmd_vel(self, msg: Twist) -> None:
        v, w = msg.linear.x, msg.angular.z
        if not (math.isfinite(v) and math.isfinite(w)):
            self.warn_throttled("cmd", f"ignoring /cmd_vel with non-finite values (linear.x={v}, angular.z={w})")
            return
        self.cmd = (float(v), float(w))
        self.cmd_time = time.monotonic()

    def on_head(self, msg: QuaternionStamped) -> None:
        q = msg.quaternion
        try:
            self.sim.set_head((q.x, q.y, q.z, q.w))
            self.head = (q.x, q.y, q.z, q.w)
        except ValueError as exc:
            self.warn_throttled("head", f"ignoring /head/orientation: {exc}")

    def on_lockstep(self, msg: TwistStamped) -> None:
        v, w = msg.twist.linear.x, msg.twist.angular.z
        if not (math.isfinite(v) and math.isfinite(w)):
            self.warn_throttled("lockstep", f"ignoring /sim/lockstep with non-finite values ({v}, {w})")
            return
        if self.lockstep.answer(stamp_to_seconds(msg.header.stamp), v, w, msg.header.frame_id):
            self.lockstep_poll()

    def lockstep_poll(self) -> None:
        """Step when the last frame was answered (or its answer is late), unless paused or held."""
        now = time.monotonic()
        if self.lockstep.hold:
            if now - self._held_repeat >= 0.5:          # where the world holds, for late subscribers
                self._held_repeat = now
                self.pub_clock.publish(Clock(clock=self.header("", self.sim.t).stamp))
                header = self.header(frames.ODOM, self.sim.t)
                self.pub_odom.publish(self.odometry(header))
                self.publish_tf(header.stamp)
            return
        late = self.lockstep.late
        if self.params["paused"] or not self.lockstep.poll(now):
            if self.lockstep.late > late:
                self.warn_throttled("lockstep-late", f"frame at t = {self.lockstep.waiting_for:.2f} s unanswered for "
                                                     f"{self.params['lockstep_timeout']:g} s by "
                                                     f"{', '.join(self.lockstep.missing())}: waiting (no step without "
                                                     f"the answers in a scripted session)", period_s=10.0)
            return
        report = self.tick(1.0 / self.params["rate"], self.lockstep.take())
        self.lockstep.published(self.sim.t, time.monotonic())
        if self.params["lockstep_hold"] and self.trial_end is not None and (
                self.sim.t >= self.trial_end - 1e-6
                or any(g.name in report.goals_reached for g in self.sim.trial_goals)):
            self.lockstep.hold, self.trial_end = True, None      # the trial ended on this frame: hold

    # -- trials (experiments) -------------------------------------------------------------------
    def on_start_trial(self, req: StartTrial.Request, res: StartTrial.Response) -> StartTrial.Response:
        goals = (GoalSpec(req.goal_name or "goal", (req.goal_x, req.goal_y), req.goal_radius),) \
            if req.goal_radius > 0 else ()
        try:
            self.sim.start_trial(req.x, req.y, req.yaw, goals)
        except ValueError as exc:
            res.success, res.message = False, str(exc)
            return res
        self.cmd = (0.0, 0.0)
        if self.lockstep is not None:
            self.lockstep.command = (0.0, 0.0)
            if self.params["lockstep_hold"]:
                self.lockstep.hold, self.trial_end = True, None
                if self.head is not None:       # a scripted subject holds its head as before: its first frame too
                    self.sim.set_head(self.head)
        if self.sim.log is not None:
            self.sim.finish_log(plot=False)
        if req.log_dir:
            try:
                log = self.sim.start_log(req.log_dir, self.params["log_rate"], {"trial": req.run_name},
                                         req.run_name or None)
            except OSError as exc:
                res.success, res.message = False, f"cannot write the trial log to '{req.log_dir}': {exc.strerror}"
                return res
            res.run_dir = str(log.dir)
            if self.lockstep is not None and self.params["lockstep_hold"]:
                # the trial runs from the next frame (with no command) to its goal or time limit
                self.trial_end = self.sim.t + req.time_limit if req.time_limit > 0 else float("inf")
                self.lockstep.restart()
                self.lockstep.hold = False
        res.success, res.sim_time = True, float(self.sim.t)
        self.get_logger().info(f"trial {req.run_name or ''} starts at ({req.x:.2f}, {req.y:.2f}), "
                               f"yaw {math.degrees(req.yaw):.0f} deg, t = {self.sim.t:.2f} s")
        return res

    def on_end_trial(self, req: EndTrial.Request, res: EndTrial.Response) -> EndTrial.Response:
        if self.lockstep is not None and self.params["lockstep_hold"]:
            self.lockstep.hold, self.trial_end = True, None
        res.success, res.sim_time = True, float(self.sim.t)
        if self.sim.log is not None:
            summary, _ = self.sim.finish_log(plot=req.plot)
            res.summary_json = json.dumps(summary)
        self.sim.trial_goals = ()
        return res

    # -- parameters -----------------------------------------------------------------------------
    def on_parameters(self, changes: dict) -> str | None:
        merged = {**self.params, **changes}
        avatar_changes = {field: changes[key] for key, field in _AVATAR_PARAMS.items() if key in changes}
        try:
            new_avatar = dataclasses.replace(self.sim.avatar.config, **avatar_changes) if avatar_changes else None
            depth = depth_sensor_config(merged) if any(k.startswith("depth_") for k in changes) else False
        except ValueError as exc:
            return str(exc)
        if new_avatar is not None:
            self.sim.avatar.config = new_avatar
        if depth is not False:
            self.sim.depth_model = (DepthSensorModel(depth, self.sim.intrinsics.fx, merged["seed"])
                                    if depth is not None else None)
        if "collision_debounce" in changes:
            self.sim.monitor.debounce_s = changes["collision_debounce"]
        return None

    def take_commands(self) -> None:
        """Apply a head turn or twist that arrived while the last frame rendered, now. rclpy's
        executor runs an overdue timer before the subscriptions that became ready meanwhile, so
        when rendering takes as long as the period (60 Hz, or a loaded machine) every head turn
        would reach the camera one frame late; the executor then finds nothing left to take."""
        for sub in self._commands:
            msg = self.take_pending(sub)
            if msg is not None:
                sub.callback(msg)

    # -- the loop -------------------------------------------------------------------------------
    def tick(self, dt: float | None = None, command: tuple[float, float] | None = None):
        """Step (by the wall clock, or ``dt`` s with ``command`` in lockstep), render, publish."""
        self.take_commands()
        t0 = time.monotonic()
        if dt is None:
            dt = 0.0 if self.last_tick is None else min(t0 - self.last_tick, MAX_STEP_S)
            timeout = self.params["cmd_timeout"]
            command = self.cmd if (timeout == 0 or t0 - self.cmd_time <= timeout) else (0.0, 0.0)
        self.last_tick = t0
        if self.params["paused"]:
            dt, command = 0.0, (0.0, 0.0)
        report = self.sim.step(dt, *command)
        t1 = time.monotonic()
        labels = self.params["publish_labels"] and self.pub_labels.get_subscription_count() > 0
        frame = self.sim.render(labels=labels)           # labels only for someone: a cheaper render
        t2 = time.monotonic()
        stamp = self.sim.t if self.lockstep is not None else None      # lockstep: stamped in sim time
        self.pub_clock.publish(Clock(clock=self.header("", self.sim.t).stamp))
        header = self.header(self.params["frame_id"], stamp)
        self.camera_info.header = header
        world_header = self.header(frames.MAP)
        world_header.stamp = header.stamp
        for event in report.collisions:                  # before the images: felt with this frame's decision
            self.pub_collisions.publish(self.collision_msg(event, world_header))
            self.get_logger().info(f"collision #{event.count} with {event.cls} '{event.name}' at {event.speed:.2f} m/s")
        self.pub_info.publish(self.camera_info)          # before the images: a node's first image finds it
        # the poses too: a node computing an image finds the head and base it was rendered with
        # (the spv node re-projects it to the newest head; a pose after it left a frame rendered
        # just before a head turn shown as if it looked the new way until its pose came)
        self.publish_tf(header.stamp)
        self.pub_pose.publish(PoseStamped(header=world_header, pose=matrix_to_pose(frame.world_from_camera)))
        self.pub_odom.publish(self.odometry(Header(stamp=header.stamp, frame_id=frames.ODOM)))
        self.pub_color.publish(array_to_image(frame.rgb, "rgb8", header))
        self.pub_depth.publish(array_to_image(frame.depth, "32FC1", header))
        if not getattr(self, "_first_frame_logged", False):   # the start of a recording is checked against it
            self._first_frame_logged = True
            h = header.stamp
            self.get_logger().info(f"first camera frame published, stamp {h.sec + 1e-9 * h.nanosec:.6f}")
        if frame.labels is not None:
            self.pub_labels.publish(array_to_image(frame.labels, "mono8", header))
        for name in report.goals_reached:
            self.get_logger().info(f"goal '{name}' reached at t = {report.t:.1f} s")
        t3 = time.monotonic()
        for key, value in (("step", t1 - t0), ("render", t2 - t1), ("publish", t3 - t2)):
            self.timings[key] += value
        self.timings["frames"] += 1
        return report

    def publish_tf(self, stamp) -> None:
        """odom → base_link (the avatar) and base_link → head (the head joint) at ``stamp``."""
        a = self.sim.avatar
        self.tf.send([(frames.ODOM, frames.BASE_LINK, a.world_from_base()),
                      (frames.BASE_LINK, frames.HEAD, a.base_from_head())], stamp)

    def odometry(self, header) -> Odometry:
        a = self.sim.avatar
        msg = Odometry(header=header, child_frame_id=frames.BASE_LINK)
        msg.pose.pose = matrix_to_pose(a.world_from_base())
        msg.twist.twist.linear.x = self.sim.linear
        msg.twist.twist.angular.z = self.sim.angular
        return msg

    @staticmethod
    def collision_msg(e: CollisionEvent, header) -> CollisionEventMsg:
        return CollisionEventMsg(header=header, other_name=e.name, other_class=e.cls,
                                 position=Point(x=e.position[0], y=e.position[1], z=e.position[2]),
                                 normal=Vector3(x=e.normal[0], y=e.normal[1], z=e.normal[2]),
                                 speed=float(e.speed), count=int(e.count))

    def close(self) -> None:
        self._close_gaze_log()
        # rclpy's context may already be shut down here: report with print, not the ROS logger
        sim = getattr(self, "sim", None)
        if sim is None:
            return
        n = self.timings["frames"]
        if n:
            print(f"sim: {n} frames; mean step {1e3 * self.timings['step'] / n:.1f} ms, render "
                  f"{1e3 * self.timings['render'] / n:.1f} ms, publish {1e3 * self.timings['publish'] / n:.1f} ms",
                  flush=True)
        if sim.log is not None:
            if self._plotting_import is not None:
                self._plotting_import.join()
            log_dir = sim.log.dir
            summary, png = sim.finish_log()
            print(f"sim: run logged in {log_dir}: {summary['duration_s']:.1f} s, {summary['path_length_m']:.1f} m, "
                  f"{summary['collisions']} collisions, goals reached {list(summary['goals_reached'])}; plot {png}",
                  flush=True)
        sim.close()
        self.sim = None


def main(argv=None) -> None:
    run_node(SimNode, argv, priority="source")


if __name__ == "__main__":
    main()
