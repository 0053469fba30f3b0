"""`raspv demo`: the virtual-world demo graph (config/demo.yaml), headless."""
from __future__ import annotations

import argparse

from raspv_bringup.graph import CONFIG_DIR
from raspv_bringup.launch_cli import launch

DEMO_GRAPH = CONFIG_DIR / "demo.yaml"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("overrides", nargs="*", metavar="NODE.PARAM:=VALUE",
                        help="override a node parameter, e.g. spv.mode:=depth sim.world:=office")


def run(args: argparse.Namespace) -> int:
    banner = ("raspv demo: the apartment in phosphenes. Open the headset client URL the bridge prints "
              "(arrow keys walk, drag turns the head, 1-9 switch modes), or drive with `raspv teleop` "
              "in another terminal. Stop with Ctrl-C.")
    return launch(str(DEMO_GRAPH), args.overrides, banner=banner)
