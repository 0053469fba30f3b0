"""`raspv param get|set|list|describe NODE [NAME [VALUE]]` (there is no `ros2 param` on PyPI)."""
from __future__ import annotations

import argparse
import os
import sys

import yaml

from raspv_bringup.middleware import apply_middleware_defaults


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=("get", "set", "list", "describe"))
    parser.add_argument("node", help="node name, e.g. spv")
    parser.add_argument("name", nargs="?", help="parameter name (get, set, describe)")
    parser.add_argument("value", nargs="?", help="new value (set), parsed as YAML unless the parameter is a string")
    parser.add_argument("--timeout", type=float, default=5.0, metavar="S")


def run(args: argparse.Namespace) -> int:
    if args.action in ("get", "set", "describe") and not args.name:
        print(f"raspv param {args.action}: give a parameter name", file=sys.stderr)
        return 2
    if args.action == "set" and args.value is None:
        print("raspv param set: give a value", file=sys.stderr)
        return 2
    apply_middleware_defaults()
    import rclpy

    from raspv_common.param_client import ParamClient, ParamError, parse_cli_value

    rclpy.init(args=["raspv", "--ros-args", "--disable-rosout-logs"])
    node = rclpy.create_node(f"raspv_param_{os.getpid()}")
    client = ParamClient(node, args.node)
    try:
        if args.action == "list":
            for name in client.list(args.timeout):
                print(name)
        elif args.action == "get":
            _, value = client.get([args.name], args.timeout)[args.name]
            print(yaml.safe_dump(value, default_flow_style=True).strip().removesuffix("...").strip())
        elif args.action == "describe":
            client.get([args.name], args.timeout)
            d = client.describe([args.name], args.timeout)[args.name]
            print(f"{args.name}: {d.description}")
            if d.additional_constraints:
                print(f"  {d.additional_constraints}")
            if d.read_only:
                print("  fixed at start (read-only)")
        else:
            current_type, _ = client.get([args.name], args.timeout)[args.name]
            ok, reason = client.set(args.name, parse_cli_value(args.value, current_type), args.timeout)
            if not ok:
                print(f"raspv param set: {args.node} refused {args.name}={args.value}: {reason or 'no reason given'}",
                      file=sys.stderr)
                return 1
            print(f"{args.name} = {args.value}")
        return 0
    except ParamError as exc:
        print(f"raspv param {args.action}: {exc}", file=sys.stderr)
        return 1
    finally:
        client.destroy()
        node.destroy_node()
        rclpy.try_shutdown()
