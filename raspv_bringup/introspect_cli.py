"""`raspv topics`, `raspv hz TOPIC`, `raspv echo TOPIC` — the common `ros2 topic` needs."""
from __future__ import annotations

import argparse
import os
import sys
import time
from collections import deque

import yaml

from rclpy.executors import ExternalShutdownException

from raspv_bringup.middleware import apply_middleware_defaults


def add_arguments_topics(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-t", "--types", action="store_true", help="show message types")
    parser.add_argument("--wait", type=float, default=5.0, metavar="S",
                        help="max seconds for discovery when no other node shows up (default 5)")


def add_arguments_hz(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("topic")
    parser.add_argument("--window", type=int, default=100, help="intervals averaged (default 100)")
    parser.add_argument("--duration", type=float, default=None, metavar="S", help="stop after S seconds")
    parser.add_argument("--wait", type=float, default=10.0, metavar="S",
                        help="seconds to wait for the topic to appear (default 10)")


def add_arguments_echo(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("topic")
    parser.add_argument("-n", "--count", type=int, default=None, help="exit after N messages")
    parser.add_argument("--once", action="store_true", help="exit after one message")
    parser.add_argument("--full", action="store_true", help="print arrays in full (default: first 16 items)")
    parser.add_argument("--wait", type=float, default=10.0, metavar="S",
                        help="seconds to wait for the topic to appear (default 10)")




class _Cli:
    """An rclpy context + node for one CLI command."""

    def __enter__(self):
        apply_middleware_defaults()
        import rclpy

        self.rclpy = rclpy
        rclpy.init(args=["raspv", "--ros-args", "--disable-rosout-logs"])
        self.node = rclpy.create_node(f"raspv_cli_{os.getpid()}")
        return self

    def __exit__(self, *exc):
        self.node.destroy_node()
        self.rclpy.try_shutdown()
        return False


def run_topics(args: argparse.Namespace) -> int:
    from raspv_common.ros_introspection import settled_topics

    with _Cli() as cli:
        topics = settled_topics(cli.node, max_wait_s=args.wait)
    own = {"/parameter_events", "/rosout"}
    for name, types in topics:
        if name in own:
            continue
        print(f"{name}  [{', '.join(types)}]" if args.types else name)
    return 0


def _resolve(cli: _Cli, topic: str, wait: float, cmd: str):
    from raspv_common.ros_introspection import message_class, qos_matching_publishers, wait_for_topic_type

    type_name = wait_for_topic_type(cli.node, topic, wait)
    if type_name is None:
        print(f"raspv {cmd}: topic {topic} did not appear within {wait:.0f} s (is the graph running? "
              f"same ROS_DOMAIN_ID?)", file=sys.stderr)
        return None
    try:
        cls = message_class(type_name)
    except ValueError as exc:
        print(f"raspv {cmd}: {exc}", file=sys.stderr)
        return None
    return cls, qos_matching_publishers(cli.node, topic)


def run_hz(args: argparse.Namespace) -> int:
    with _Cli() as cli:
        resolved = _resolve(cli, args.topic, args.wait, "hz")
        if resolved is None:
            return 1
        cls, qos = resolved
        stamps: deque[float] = deque(maxlen=args.window + 1)
        count = [0]

        def on_msg(_raw: bytes) -> None:
            stamps.append(time.monotonic())
            count[0] += 1

        cli.node.create_subscription(cls, args.topic, on_msg, qos, raw=True)
        start = last_print = time.monotonic()
        try:
            while cli.rclpy.ok():
                cli.rclpy.spin_once(cli.node, timeout_sec=0.05)
                now = time.monotonic()
                if now - last_print >= 1.0:
                    last_print = now
                    print(_rate_line(stamps, count[0]) if len(stamps) > 1 else f"no messages on {args.topic} yet",
                          flush=True)
                if args.duration is not None and now - start >= args.duration:
                    break
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        return 0 if count[0] > 0 else 1


def _rate_line(stamps: deque, total: int) -> str:
    s = list(stamps)
    dts = [b - a for a, b in zip(s, s[1:])]
    mean = sum(dts) / len(dts)
    std = (sum((d - mean) ** 2 for d in dts) / len(dts)) ** 0.5
    return (f"average rate: {1.0 / mean:.2f} Hz  min {min(dts) * 1e3:.1f} ms  max {max(dts) * 1e3:.1f} ms  "
            f"std {std * 1e3:.1f} ms  window {len(dts)}  total {total}")


def run_echo(args: argparse.Namespace) -> int:
    from raspv_common.ros_introspection import message_to_plain

    limit = 1 if args.once else args.count
    with _Cli() as cli:
        resolved = _resolve(cli, args.topic, args.wait, "echo")
        if resolved is None:
            return 1
        cls, qos = resolved
        seen = [0]

        def on_msg(msg) -> None:
            if limit is not None and seen[0] >= limit:
                return
            seen[0] += 1
            text = yaml.safe_dump(message_to_plain(msg, None if args.full else 16), sort_keys=False,
                                  default_flow_style=None, width=120)
            print(text + "---", flush=True)

        cli.node.create_subscription(cls, args.topic, on_msg, qos)
        try:
            while cli.rclpy.ok() and (limit is None or seen[0] < limit):
                cli.rclpy.spin_once(cli.node, timeout_sec=0.1)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        return 0
