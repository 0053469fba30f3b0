"""`subject` node: a scripted subject (virtual patient) in the graph.

Sees only what a subject sees: ``/spv/map`` (where the phosphenes are) and ``/spv/frame`` (the
brightness of each), and feels what a body feels: a bump (``/sim/collisions``, stamped with the
camera frame of its step) is felt with that frame, before the policy decides — as
:func:`~raspv_experiments.quick_trial.quick_trial` calls ``touch()``. For every frame it publishes a walking command on ``/cmd_vel`` and the head
it holds on ``/head/orientation``, and answers the frame on ``/sim/lockstep`` (TwistStamped,
stamped with the frame's source stamp) so a simulator in lockstep steps at once. It presses
'start' when the experiment shows instructions (``/experiment/instructions`` →
``/experiment/response``). The policies are in :mod:`raspv_experiments.policies`.

Each trial starts with a fresh policy, seeded by the subject's seed and the trial number, when
its instructions come; the instructions of a scripted session also say where the goal is from
the start (``goal_from_start`` [m], x ahead, y left: what a person is told) and the sim time
``after`` which the trial's frames come (earlier frames still in flight are answered but not
seen), so a trial's commands depend on that trial's frames only. The policy's clock is the
trial's (:class:`~raspv_experiments.trial_clock.TrialClock`: 0 at its start, frame periods summed
as the simulator sums them), so its time comparisons do not depend on when in the session the
trial ran, and match a quick trial's to the bit.

With ``gaze`` ``model`` or ``trace`` it also moves its eyes (:mod:`raspv_experiments.scripted_gaze`):
each trial plays a gaze trace from the trial's start (the model seeded by the trial's seed), and
every frame publishes the samples whose sim time came on ``/gaze/direction`` (Vector3Stamped,
head frame, stamped in sim time; (0, 0, 0) while it blinks), for the spv node's ``gaze_mode``
and the trial's log. When the field is drawn displaced (``PhospheneFrame.field_offset_*``) it
sees each phosphene where it is drawn, not where it samples (the phosphene drawn nearest to
each position of its map): gaze-locked content is then seen in the wrong place.
"""
from __future__ import annotations

import json
import math

import numpy as np
from geometry_msgs.msg import Quaternion, QuaternionStamped, Twist, TwistStamped, Vector3, Vector3Stamped
from raspv_msgs.msg import CollisionEvent, PhospheneFrame, PhospheneMap
from std_msgs.msg import String

from raspv_common import topics
from raspv_common.frames import BASE_LINK
from raspv_common.conversions import stamp_to_seconds
from raspv_common.node import RaspvNode, run_node
from raspv_common.qos import COMMAND_QOS, EVENT_QOS, GAZE_QOS, LATCHED_QOS, SENSOR_QOS
from raspv_experiments.design import trial_seed
from raspv_experiments.policies import Command, PhospheneLayout, PolicyConfig, make_policy
from raspv_experiments.scripted_gaze import (GazeModelConfig, GazeScript, displayed_layout_index, load_trace,
                                             model_trace)
from raspv_experiments.subject_params import PARAMS
from raspv_experiments.trial_clock import TrialClock
from raspv_common.rotations import head_quaternion


def policy_config(p: dict, seed: int | None = None) -> PolicyConfig:
    return PolicyConfig(max_linear=p["max_linear"], max_angular=p["max_angular"], head_pitch_deg=p["head_pitch_deg"],
                        eye_height=p["eye_height"], lookahead=p["lookahead"], bright_ratio=p["bright_ratio"],
                        noise=p["noise"], seed=p["seed"] if seed is None else seed,
                        reaction_time_s=p["reaction_time_s"], min_brightness=p["min_brightness"],
                        contrast_threshold=p["contrast_threshold"], perception_noise=p["perception_noise"])


class SubjectNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("subject", PARAMS)
        self.layout: PhospheneLayout | None = None
        self.policy = None
        self.trial_seed = self.params["seed"]
        self.answered_instructions = ""
        self.goal: tuple[float, float] | None = None     # the trial's goal from its start [m] (x ahead, y left)
        self.after = -1.0                                # frames up to this sim time are from before the trial
        self.clock = TrialClock()
        self.frames = 0
        self.pub_cmd = self.create_publisher(Twist, topics.CMD_VEL, COMMAND_QOS)
        self.pub_head = self.create_publisher(QuaternionStamped, topics.HEAD_ORIENTATION, COMMAND_QOS)
        self.pub_step = self.create_publisher(TwistStamped, topics.SIM_LOCKSTEP, COMMAND_QOS)
        self.pub_response = self.create_publisher(String, topics.EXPERIMENT_RESPONSE, EVENT_QOS)
        self.pub_gaze = self.create_publisher(Vector3Stamped, topics.GAZE_DIRECTION, GAZE_QOS)
        self.gaze: GazeScript | None = None
        self._seen_at: tuple[tuple, np.ndarray] | None = None      # ((map id, offset), displayed index)
        self.spacing_px = 1.0
        self.create_subscription(PhospheneMap, topics.SPV_MAP, self.on_map, LATCHED_QOS)
        self.create_subscription(PhospheneFrame, topics.SPV_FRAME, self.on_frame, SENSOR_QOS)
        self.create_subscription(String, topics.EXPERIMENT_INSTRUCTIONS, self.on_instructions, LATCHED_QOS)
        self._collisions = self.create_subscription(CollisionEvent, topics.SIM_COLLISIONS, self.on_collision, EVENT_QOS)
        self._bumps: list[float] = []                    # sim times [s] of bumps not yet felt
        self.get_logger().info(f"scripted subject: policy {self.params['policy']}, seed {self.params['seed']}")

    def _new_policy(self, params: dict) -> None:
        if self.layout is not None:
            extra = {"model": params["model"]} if params["policy"] == "learned" else {}
            self.policy = make_policy(params["policy"], self.layout, policy_config(params, self.trial_seed),
                                      goal=self.goal, **extra)

    def on_parameters(self, changes):
        merged = {**self.params, **changes}
        self._new_policy(merged)
        if {"gaze", "gaze_trace", "gaze_rate"} & set(changes):
            try:
                self.gaze = None                    # (re)started from the next frame
                if merged["gaze"] == "trace" and merged["gaze_trace"]:
                    load_trace(merged["gaze_trace"])
            except ValueError as exc:
                return str(exc)
        return None

    def on_map(self, msg: PhospheneMap) -> None:
        self.spacing_px = float(msg.spacing_x_px) or 1.0
        self.layout = PhospheneLayout(np.asarray(msg.x, float), np.asarray(msg.y, float), int(msg.width),
                                      int(msg.height), float(msg.focal_px), int(msg.map_id))
        self._new_policy(self.params)

    def on_instructions(self, msg: String) -> None:
        try:
            info = json.loads(msg.data)
        except json.JSONDecodeError:
            return
        key = str(info.get("id", ""))
        if not info.get("waiting") or key == self.answered_instructions:
            return
        self.answered_instructions = key
        # a new trial: the same virtual subject, its noise reseeded per trial (reproducible)
        self.trial_seed = trial_seed(int(self.params["seed"]), int(info.get("trial", 0)))
        goal = info.get("goal_from_start")
        self.goal = (float(goal[0]), float(goal[1])) if isinstance(goal, list) and len(goal) == 2 else None
        self.after = float(info.get("after", -1.0))
        self.clock = TrialClock(self.after)
        self._new_policy(self.params)
        self.gaze = self._gaze_script(self.params, self.after) if self.after >= 0 else None   # else from the next frame
        self._publish_head(math.radians(self.params["head_pitch_deg"]))     # the head it will hold, before starting
        if self.params["auto_start"]:
            self.pub_response.publish(String(data=json.dumps({"action": "start", "id": key, "by": "subject"})))

    def _gaze_script(self, p: dict, origin: float) -> GazeScript | None:
        """The trial's eye movements (None: ``gaze`` none), played from sim time ``origin``."""
        if p["gaze"] == "model":
            duration = 600.0                        # s; a longer trial plays it again
            return GazeScript(model_trace(duration, self.trial_seed, GazeModelConfig(rate_hz=p["gaze_rate"])), origin)
        if p["gaze"] == "trace" and p["gaze_trace"]:
            return GazeScript(load_trace(p["gaze_trace"]), origin)
        return None

    def _publish_gaze(self, now: float) -> None:
        """The gaze samples up to sim time ``now`` [s]."""
        if self.gaze is None:
            return
        for stamp, direction in self.gaze.due(now):
            x, y, z = direction if direction is not None else (0.0, 0.0, 0.0)
            self.pub_gaze.publish(Vector3Stamped(header=self.header("head", stamp),
                                                 vector=Vector3(x=float(x), y=float(y), z=float(z))))

    def _as_seen(self, msg: PhospheneFrame, brightness: np.ndarray) -> np.ndarray:
        """The brightness at each phosphene's place on the display when the field is drawn shifted."""
        offset = (round(msg.field_offset_x_px), round(msg.field_offset_y_px))
        if offset == (0, 0):
            return brightness
        key = (msg.map_id, offset)
        if self._seen_at is None or self._seen_at[0] != key:
            centres = np.column_stack([self.layout.x, self.layout.y])
            self._seen_at = (key, displayed_layout_index(centres, offset, self.spacing_px))
        index = self._seen_at[1]
        return np.where(index >= 0, brightness[np.maximum(index, 0)], 0.0)

    def on_collision(self, msg: CollisionEvent) -> None:
        """A bump (stamped with the camera frame of the step it happened in): felt with that frame."""
        self._bumps.append(stamp_to_seconds(msg.header.stamp))

    def take_collisions(self) -> None:
        """Take the bumps already delivered before deciding a frame: the simulator publishes a
        step's collisions before its camera frame, but the executor may hand this node the
        phosphene frame (which came through the spv node) first; the bump was then felt one frame
        late and the graph trial parted from the quick trial (issue 33)."""
        while (msg := self.take_pending(self._collisions)) is not None:
            self.on_collision(msg)

    def _felt(self, t: float) -> bool:
        """Whether the body bumped into something during this trial up to the frame at sim time ``t``."""
        felt = [s for s in self._bumps if s <= t + 1e-6]
        self._bumps = [s for s in self._bumps if s > t + 1e-6]
        return any(s > self.after + 1e-6 for s in felt)

    def on_frame(self, msg: PhospheneFrame) -> None:
        command = Command(0.0, 0.0, math.radians(self.params["head_pitch_deg"]))   # standing, head held
        t = msg.source_stamp.sec + 1e-9 * msg.source_stamp.nanosec
        self.take_collisions()
        bumped = self._felt(t)
        if self.policy is not None and msg.map_id == self.layout.map_id and t > self.after + 1e-6:
            brightness = np.asarray(msg.brightness, dtype=float)
            if brightness.shape == self.layout.x.shape:
                brightness = self._as_seen(msg, brightness)
                self.policy.show(msg.mode, msg.overlays)
                if bumped:                          # touch, as quick_trial: before the frame's decision
                    self.policy.touch()
                command = self.policy.act(brightness, self.clock.at(t) if self.after >= 0 else t)
        self.frames += 1
        if t > self.after + 1e-6:
            if self.gaze is None and self.params["gaze"] != "none":
                self.gaze = self._gaze_script(self.params, t)
            self._publish_gaze(t)                   # its eyes moved up to this frame (sim time)
        twist = Twist()
        twist.linear.x, twist.angular.z = command.linear, command.angular
        self._publish_head(command.head_pitch)
        self.pub_cmd.publish(twist)
        answer = TwistStamped(twist=twist)
        answer.header.stamp = msg.source_stamp
        answer.header.frame_id = BASE_LINK
        self.pub_step.publish(answer)

    def _publish_head(self, pitch: float) -> None:
        q = head_quaternion(0.0, pitch, 0.0)
        self.pub_head.publish(QuaternionStamped(header=self.header(BASE_LINK),
                                                quaternion=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])))


def main(argv=None) -> None:
    run_node(SubjectNode, argv)


if __name__ == "__main__":
    main()
