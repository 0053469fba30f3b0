"""The ``raspv`` command line (ROS 2's ``ros2`` CLI is not on PyPI, so we ship what users need).

Each subcommand is a module exposing ``add_arguments(parser)`` and ``run(args) -> int``;
modules are imported only when their command runs, so ``raspv --help`` stays fast.
"""
from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys

from raspv_common.extras import MissingExtra

# name → (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "launch": ("raspv_bringup.launch_cli", "start a node graph from a YAML file and supervise it"),
    "export-launch": ("raspv_bringup.export_launch_cli", "write a graph as a ros2 launch file (system ROS 2, colcon build)"),
    "demo": ("raspv_bringup.demo_cli", "run the virtual-world demo graph (config/demo.yaml)"),
    "doctor": ("raspv_bringup.doctor_cli", "what this machine can do: Python, ROS, browser, cameras, extras, disk, CPU"),
    "topics": ("raspv_bringup.introspect_cli", "list topics and their types"),
    "hz": ("raspv_bringup.introspect_cli", "measure the publishing rate of a topic"),
    "echo": ("raspv_bringup.introspect_cli", "print messages of a topic"),
    "param": ("raspv_bringup.param_cli", "get, set or list a running node's parameters"),
    "nodes": ("raspv_bringup.nodes_cli", "list the node kinds and their parameters"),
    "bench": ("raspv_bench.bench_cli", "benchmarks with figures and ratios against peers"),
    "sim": ("raspv_sim.sim_cli", "world files and logged runs: check, map, render, plot"),
    "hmd-client": ("raspv_hmd.client_cli", "reference headset client: receive frames, send head motion, measure latency"),
    "teleop": ("raspv_bringup.teleop_cli", "drive the avatar and turn its head from this terminal"),
    "bag": ("raspv_bringup.bag_cli", "record, play, inspect and repair bags; build one from RGB-D image files"),
    "experiment": ("raspv_experiments.experiment_cli", "experiments: protocols, sessions with subjects, sweeps, reports"),
    "render": ("raspv_bringup.render_cli", "render a bag into a phosphene video (mp4) and/or PNG frames, offline"),
    "learn": ("raspv_learn.learn_cli", "learned encoders: render the dataset, train through the differentiable twin, "
                                       "compare with the hand-designed modes"),
    "slam": ("raspv_slam.slam_cli", "RGB-D SLAM: build a map from a recording, inspect a map, evaluate against ground truth, align a map to a building map"),
    "camera": ("raspv_camera.camera_cli", "real RGB-D cameras: list connected devices, show modes, import recordings"),
}


# commands that start a graph: SIGINT stops them from their first line on (see main)
GRAPH_COMMANDS = frozenset({"launch", "demo"})


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="raspv", description="RASPV: augmented simulated prosthetic vision on ROS 2")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if command == name:  # import only the module of the command being run
            mod = importlib.import_module(module)
            adder = getattr(mod, f"add_arguments_{name.replace('-', '_')}", None) or mod.add_arguments
            adder(p)
            p.set_defaults(_module=mod, _name=name)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    if command in GRAPH_COMMANDS and signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        # A shell starts a background job (`raspv launch … &`) with SIGINT ignored, and Python
        # keeps it so: a `kill -INT` before the launcher's own handler is installed — after
        # its imports and the graph's checks, seconds on a loaded machine — was lost and the
        # graph ran on. From here on it is a KeyboardInterrupt (exit 130, nothing started).
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        parser = build_parser(command if command in COMMANDS else None)
        args = parser.parse_args(argv)
        if not getattr(args, "command", None):
            parser.print_help()
            return 0
        mod = args._module
        runner = getattr(mod, f"run_{args._name.replace('-', '_')}", None) or mod.run
        return int(runner(args) or 0)
    except MissingExtra as exc:  # an optional package this command needs: the line names its install
        print(f"raspv {command}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    except ImportError as exc:        # a C extension's import interrupted by an early SIGINT
        from raspv_bringup.node_entry import interrupted
        if interrupted(exc):
            return 130
        raise
    except BrokenPipeError:  # output piped into `head` & co. that stopped reading
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
