"""The `sim` and `teleop` nodes in real graphs: source topics, driving into a wall, the head,
logs, one-line configuration errors, and the keyboard through a pseudo-terminal."""
from __future__ import annotations

import json
import math
import os
import pty
import select
import subprocess
import sys
import termios
import time

import numpy as np
import pytest
import yaml
from geometry_msgs.msg import PoseStamped, Quaternion, QuaternionStamped, Twist
from nav_msgs.msg import Odometry
from raspv_msgs.msg import CollisionEvent
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import String

from raspv_bringup.testing import RunningGraph
from raspv_common import topics
from raspv_common.conversions import depth_from_image, image_to_array, pose_to_matrix
from raspv_common.qos import LATCHED_QOS
from raspv_sim.avatar import head_quaternion


pytestmark = pytest.mark.integration

BOX_ROOM = {   # 6 × 4 m room, the avatar facing the east wall (inner face at x = 5.94) from x = 1
    "floor": {"from": [0, 0], "to": [6, 4]},
    "rooms": [{"name": "box", "from": [0, 0], "to": [6, 4]}],
    "furniture": [{"type": "table", "name": "desk", "position": [3, 3.3]}],
    "spawn": {"position": [1, 2], "yaw": 0},
}


def sim_graph(params: dict) -> dict:
    return {"launch": {"nodes": [{"kind": "sim"}]},
            "sim": {"ros__parameters": {"width": 160, "height": 120, "rate": 15.0, **params}}}


class TestTheApartmentGraph:
    """One sim graph in the apartment (started once, stopped after the class) for two tests in
    this order: the source topics at the spawn, then the head turned and the eye raised."""

    @pytest.fixture(scope="class")
    def apartment(self, tmp_path_factory, ros_domain):
        g = RunningGraph(sim_graph({"world": "apartment"}), tmp_path_factory.mktemp("apartment"))
        yield g
        code = g.stop()
        assert code == 0, f"the apartment graph ended with exit code {code}:\n{g.output[-3000:]}"

    def test_sim_publishes_the_source_topics_and_ground_truth(self, apartment, probe):
        g = apartment
        color = probe.wait_for_message(topics.COLOR, Image, timeout=60)
        assert (color.encoding, color.width, color.height) == ("rgb8", 160, 120)
        assert color.header.frame_id == "camera_color_optical_frame"
        assert image_to_array(color).std() > 5
        depth = depth_from_image(probe.wait_for_message(topics.DEPTH, Image))
        assert np.isfinite(depth).mean() > 0.5 and np.nanmax(depth) <= 8.0
        info = probe.wait_for_message(topics.CAMERA_INFO, CameraInfo)
        f = 160 / (2 * math.tan(math.radians(30)))
        assert list(info.k) == pytest.approx([f, 0, 79.5, 0, f, 59.5, 0, 0, 1])
        pose = probe.wait_for_message(topics.CAMERA_POSE, PoseStamped)
        T = pose_to_matrix(pose.pose)
        assert pose.header.frame_id == "map"
        assert T[:3, 3] == pytest.approx([0.7 + 0.08, 3.8, 1.6], abs=1e-6)   # spawn, eye 8 cm ahead of the neck
        assert T[:3, 2] == pytest.approx([1, 0, 0], abs=1e-6)                # looking along the corridor (+x)
        odom = probe.wait_for_message(topics.ODOM, Odometry)
        assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
        assert odom.pose.pose.position.x == pytest.approx(0.7)
        labels = probe.wait_for_message(topics.SIM_LABELS, Image)
        assert labels.encoding == "mono8"
        table = json.loads(probe.wait_for_message(topics.SIM_CLASSES, String, qos=LATCHED_QOS).data)
        assert table["world"] == "apartment" and table["classes"][:3] == ["none", "floor", "wall"]
        present = {table["classes"][i] for i in np.unique(image_to_array(labels))}
        assert {"floor", "wall"} <= present
        g.wait_for_output(r"renderer: (EGL OpenGL \(.+\)|TinyRenderer \(software; .+\));")   # says which

    def test_head_orientation_turns_the_camera_pose_only(self, apartment, probe):
        probe.wait_for_message(topics.CAMERA_POSE, PoseStamped, timeout=60)
        pub = probe.publisher(topics.HEAD_ORIENTATION, QuaternionStamped, wait_for_subscribers=1)
        x, y, z, w = head_quaternion(0.0, math.radians(20), math.radians(45))
        msg = QuaternionStamped(quaternion=Quaternion(x=x, y=y, z=z, w=w))
        msg.header.frame_id = "base_link"

        def turned(m: PoseStamped) -> bool:
            pub.publish(msg)
            axis = pose_to_matrix(m.pose)[:3, 2]
            return abs(math.degrees(math.atan2(axis[1], axis[0])) - 45.0) < 0.01
        pose = probe.wait_for_message(topics.CAMERA_POSE, PoseStamped, predicate=turned, timeout=30)
        axis = pose_to_matrix(pose.pose)[:3, 2]
        assert math.degrees(math.asin(-axis[2])) == pytest.approx(20.0, abs=0.01)     # looking 20° down
        odom = probe.wait_for_message(topics.ODOM, Odometry)
        assert odom.pose.pose.orientation.z == pytest.approx(0.0, abs=1e-9)        # the base did not turn
        # run-time parameters: the eye height moves the camera; the body's shape cannot change
        assert probe.set_params("sim", {"eye_height": 1.2}) == [("eye_height", True, "")]
        pitch = math.radians(20)     # neck pivot 0.1 m below the eye; eye 8 cm ahead, 10 cm up, turned with the head
        eye_z = 1.2 - 0.1 + 0.1 * math.cos(pitch) - 0.08 * math.sin(pitch)
        probe.wait_for_message(topics.CAMERA_POSE, PoseStamped, predicate=lambda m: abs(m.pose.position.z - eye_z) < 1e-6)
        [(name, ok, reason)] = probe.set_params("sim", {"max_step": 0.1})
        assert not ok and "read-only parameter: max_step" in reason


def test_driving_into_a_wall_stops_the_avatar_publishes_a_collision_and_logs_it(graph, probe, tmp_path):
    world = tmp_path / "box.yaml"
    world.write_text(yaml.safe_dump(BOX_ROOM))
    g = graph(sim_graph({"world": str(world), "renderer": "tiny", "log_dir": str(tmp_path / "runs"), "log_rate": 5.0}))
    g.wait_for_output(r"logging the run to ", timeout=60)
    collisions = probe.subscribe(topics.SIM_COLLISIONS, CollisionEvent)
    pub = probe.publisher(topics.CMD_VEL, Twist, wait_for_subscribers=1)
    forward = Twist()
    forward.linear.x = 1.5
    deadline = time.monotonic() + 30
    while not collisions.messages and time.monotonic() < deadline:
        pub.publish(forward)
        time.sleep(0.1)
    event = collisions.wait(1, timeout=5)[0]
    assert (event.other_name, event.other_class, event.count) == ("box/east", "wall", 1)
    assert event.header.frame_id == "map" and event.speed == pytest.approx(1.5)
    assert event.normal.x == pytest.approx(-1.0, abs=1e-3)
    for _ in range(10):              # keep pushing: the avatar stays at the wall, no new event
        pub.publish(forward)
        time.sleep(0.1)
    odom = probe.wait_for_message(topics.ODOM, Odometry)
    assert odom.pose.pose.position.x == pytest.approx(5.94 - 0.25, abs=0.02)
    assert len(collisions.messages) == 1
    g.stop()
    runs = list((tmp_path / "runs").iterdir())
    assert len(runs) == 1
    events = [json.loads(line) for line in (runs[0] / "events.jsonl").read_text().splitlines()]
    assert [(e["event"], e["name"]) for e in events] == [("collision", "box/east")]
    assert json.loads((runs[0] / "summary.json").read_text())["collisions"] == 1
    assert (runs[0] / "trajectory.png").is_file()
    assert "run logged in" in g.output


def test_a_broken_world_is_a_one_line_configuration_error(graph, tmp_path):
    world = tmp_path / "broken.yaml"
    world.write_text(yaml.safe_dump({**BOX_ROOM, "furniture": [{"type": "sofa", "position": [3, 3], "size": [2, 1]}]}))
    g = graph(sim_graph({"world": str(world)}))          # the launcher checks the world before starting anything
    g.proc.wait(timeout=60)
    assert g.stop() == 2
    [line] = [x for x in g.output.splitlines() if x.strip()]
    assert "sim.ros__parameters.world:" in line
    assert line.endswith("furniture[0] (sofa): 'size' must be 3 positive numbers, got [2, 1]")
    # the node itself, started without the launcher, says the same in one line
    node = subprocess.run([sys.executable, "-m", "raspv_sim.sim_node", "--ros-args", "-p", f"world:={world}"],
                          capture_output=True, text=True, timeout=120)
    assert node.returncode == 2 and "Traceback" not in node.stdout + node.stderr
    assert node.stderr.strip().endswith("furniture[0] (sofa): 'size' must be 3 positive numbers, got [2, 1]")


def test_teleop_without_a_terminal_says_so_in_one_line():
    proc = subprocess.run([sys.executable, "-m", "raspv_sim.teleop_node"], stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert "its standard input is not a terminal; run it in a terminal of its own" in proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout


def _read_until(fd: int, text: str, timeout: float = 30.0) -> str:
    out = ""
    deadline = time.monotonic() + timeout
    while text not in out:
        if time.monotonic() > deadline:
            raise TimeoutError(f"{text!r} not in teleop output: {out[-500:]!r}")
        if select.select([fd], [], [], 0.2)[0]:
            try:
                out += os.read(fd, 4096).decode(errors="replace")
            except OSError:
                break
    return out


def test_teleop_drives_from_keys_in_a_terminal_and_restores_it(probe, ros_domain):
    pid, fd = pty.fork()
    if pid == 0:   # child: the teleop node on the pseudo-terminal
        os.execv(sys.executable, [sys.executable, "-m", "raspv_sim.teleop_node"])
    try:
        _read_until(fd, "Ctrl-C quits")
        cooked = termios.tcgetattr(fd)
        assert not cooked[3] & termios.ECHO            # keys are not echoed while it runs
        probe.wait_for_message(topics.CMD_VEL, Twist, timeout=30)   # discovered

        def pressing_i(m: Twist) -> bool:    # like a held key: 'i' again on every message
            os.write(fd, b"i")
            return m.linear.x > 0
        twist = probe.wait_for_message(topics.CMD_VEL, Twist, predicate=pressing_i, timeout=30)
        assert (twist.linear.x, twist.angular.z) == pytest.approx((0.5, 0.0))
        os.write(fd, b"\x1b[D\x1b[D")                  # two arrows left: head yaw +10°
        head = probe.wait_for_message(topics.HEAD_ORIENTATION, QuaternionStamped,
                                      predicate=lambda m: m.quaternion.z > 0.01, timeout=30)
        assert 2 * math.degrees(math.asin(head.quaternion.z)) == pytest.approx(10.0, abs=1e-6)
        assert head.header.frame_id == "base_link"
        os.write(fd, b"\x03")                          # Ctrl-C
        _, status = os.waitpid(pid, 0)
        pid = 0
        assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0
        restored = termios.tcgetattr(fd)
        assert restored[3] & termios.ECHO and restored[3] & termios.ICANON
    finally:
        if pid:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
        os.close(fd)


def test_lockstep_keeps_every_answer_of_a_frame(graph, probe):
    """The subject and the planner answer each frame on /sim/lockstep; a queue of one kept only the
    later answer when both came together, and the world stepped after the timeout with the
    previous command (a lockstep run parted from its repetition at load 10-16). Both answers
    of 15 frames come back to back here; the timeout (30 s) never fires."""
    from geometry_msgs.msg import TwistStamped
    from raspv_common.qos import COMMAND_QOS

    graph(sim_graph({"world": "apartment", "step_mode": "lockstep", "lockstep_participants": ["planner"],
                     "lockstep_timeout": 30.0}))
    infos = probe.subscribe(topics.CAMERA_INFO, CameraInfo, wait_for_publishers=1, timeout=90)
    subject = probe.publisher(topics.SIM_LOCKSTEP, TwistStamped, COMMAND_QOS, wait_for_subscribers=1, timeout=60)
    planner = probe.publisher(topics.SIM_LOCKSTEP, TwistStamped, COMMAND_QOS, wait_for_subscribers=1, timeout=60)

    def stamp(m):
        return m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec

    frame = infos.wait(1, timeout=60)[0]
    for k in range(15):
        for pub, who in ((planner, "planner"), (subject, "base_link")):
            answer = TwistStamped()
            answer.header.stamp, answer.header.frame_id = frame.header.stamp, who
            answer.twist.angular.z = 0.3 if who == "base_link" else 0.0
            pub.publish(answer)
        last = stamp(frame)
        frame = infos.wait(1, timeout=10, predicate=lambda m: stamp(m) > last + 1e-6)[0]
        assert stamp(frame) == pytest.approx(last + 1 / 15.0, abs=1e-6), k     # one step per answered frame
