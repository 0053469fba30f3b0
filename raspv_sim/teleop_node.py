"""`teleop` node: drive the avatar and turn its head from the keyboard, in a terminal.

Publishes ``/cmd_vel`` (Twist) and ``/head/orientation`` (QuaternionStamped, frame ``base``) at
``rate`` Hz; key mapping in :mod:`raspv_sim.teleop_keys`. It reads the terminal in cbreak mode
(no echo, keys without Enter, Ctrl-C still stops it) and restores the terminal on exit. Run it
in its own terminal next to the graph: ``python -m raspv_sim.teleop_node``.
"""
from __future__ import annotations

import os
import select
import sys
import termios
import threading
import time
import tty

from geometry_msgs.msg import Quaternion, QuaternionStamped, Twist

from raspv_common import topics
from raspv_common.frames import BASE_LINK
from raspv_common.node import ConfigurationError, RaspvNode, run_node
from raspv_common.qos import COMMAND_QOS
from raspv_common.rotations import head_quaternion
from raspv_sim.teleop_keys import HELP, KeyDecoder, TeleopConfig, TeleopKeys
from raspv_sim.teleop_params import PARAMS

NOT_A_TTY = ("teleop reads the keyboard, but its standard input is not a terminal; run it in a terminal of its "
             "own: python -m raspv_sim.teleop_node")


def teleop_config(p: dict) -> TeleopConfig:
    return TeleopConfig(linear_speed=p["linear_speed"], angular_speed=p["angular_speed"], key_timeout=p["key_timeout"],
                        head_step_deg=p["head_step_deg"])


class TeleopNode(RaspvNode):
    def __init__(self) -> None:
        super().__init__("teleop", PARAMS)
        self.fd = sys.stdin.fileno() if sys.stdin is not None else -1
        if self.fd < 0 or not os.isatty(self.fd):
            raise ConfigurationError(NOT_A_TTY)
        self.keys = TeleopKeys(teleop_config(self.params))
        self.lock = threading.Lock()
        self.saved_tty = termios.tcgetattr(self.fd)
        tty.setcbreak(self.fd)
        self.pub_cmd = self.create_publisher(Twist, topics.CMD_VEL, COMMAND_QOS)
        self.pub_head = self.create_publisher(QuaternionStamped, topics.HEAD_ORIENTATION, COMMAND_QOS)
        self.running = True
        self.reader = threading.Thread(target=self.read_keys, daemon=True)
        self.reader.start()
        self.create_timer(1.0 / self.params["rate"], self.publish)
        print(HELP + "\nCtrl-C quits.\n", flush=True)

    def on_parameters(self, changes: dict) -> str | None:
        with self.lock:
            if "linear_speed" in changes:
                self.keys.linear_speed = changes["linear_speed"]
            if "angular_speed" in changes:
                self.keys.angular_speed = changes["angular_speed"]
            merged = {**self.params, **changes}
            speeds = (self.keys.linear_speed, self.keys.angular_speed)
            self.keys.config = teleop_config(merged)
            self.keys.linear_speed, self.keys.angular_speed = speeds
        return None

    def read_keys(self) -> None:
        decoder = KeyDecoder()
        while self.running:
            ready, _, _ = select.select([self.fd], [], [], 0.1)
            if not ready:
                pressed = decoder.flush()
            else:
                try:
                    data = os.read(self.fd, 64)
                except OSError:
                    return
                if not data:   # end of input
                    return
                pressed = decoder.feed(data)
            for key in pressed:
                with self.lock:
                    status = self.keys.handle(key, time.monotonic())
                print(f"\r\x1b[K{status}", end="", flush=True)
                if self.keys.quit:
                    os.kill(os.getpid(), 2)   # Ctrl-C read as a key (the terminal had ISIG off)
                    return

    def publish(self) -> None:
        with self.lock:
            v, w = self.keys.velocity(time.monotonic())
            roll, pitch, yaw = self.keys.head_angles()
        twist = Twist()
        twist.linear.x, twist.angular.z = v, w
        self.pub_cmd.publish(twist)
        x, y, z, qw = head_quaternion(roll, pitch, yaw)
        self.pub_head.publish(QuaternionStamped(header=self.header(BASE_LINK), quaternion=Quaternion(x=x, y=y, z=z, w=qw)))

    def close(self) -> None:
        self.running = False
        saved = getattr(self, "saved_tty", None)
        if saved is not None:
            termios.tcsetattr(self.fd, termios.TCSADRAIN, saved)
            self.saved_tty = None
            print("", flush=True)
        if hasattr(self, "pub_cmd"):
            try:
                self.pub_cmd.publish(Twist())   # leave the avatar standing
            except Exception:  # the context may already be shut down
                pass


def main(argv=None) -> None:
    run_node(TeleopNode, argv)


if __name__ == "__main__":
    main()
