"""`raspv teleop`: the keyboard teleoperation node in this terminal (it needs a terminal, so it
is not part of graph files; run it beside `raspv demo`)."""
from __future__ import annotations

import argparse

from raspv_bringup.middleware import apply_middleware_defaults


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("ros_args", nargs=argparse.REMAINDER,
                        help="extra ROS arguments, e.g. --ros-args -p max_linear:=1.0")


def run(args: argparse.Namespace) -> int:
    apply_middleware_defaults()
    from raspv_sim.teleop_node import main

    main(["raspv_teleop", *args.ros_args])
    return 0
