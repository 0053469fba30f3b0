"""`raspv launch FILE [NODE.PARAM:=VALUE ...]`: start a graph and supervise it until Ctrl-C."""
from __future__ import annotations

import argparse
import signal
import sys

from raspv_bringup.graph import GraphError, load_graph, resolve_graph_path
from raspv_bringup.supervisor import Supervisor


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("graph", help="graph YAML file, or the name of one in config/ (e.g. demo)")
    parser.add_argument("overrides", nargs="*", metavar="NODE.PARAM:=VALUE",
                        help="override a node parameter, e.g. spv.mode:=depth")
    parser.add_argument("--check", action="store_true", help="only validate the graph file")
    parser.add_argument("--shutdown-timeout", type=float, default=8.0, metavar="S",
                        help="seconds to wait for nodes after SIGINT before SIGTERM (default 8)")


def launch(graph_name: str, overrides: list[str], check: bool = False, shutdown_timeout: float = 8.0,
           banner: str | None = None) -> int:
    path = resolve_graph_path(graph_name)
    try:
        graph = load_graph(path, overrides)
    except GraphError as exc:
        for line in exc.errors:
            print(f"raspv launch: {line}", file=sys.stderr)
        return 2
    if check:
        print(f"raspv launch: {path}: OK ({', '.join(n.name for n in graph.nodes)})")
        return 0
    sup = Supervisor(graph, shutdown_timeout_s=shutdown_timeout)

    def on_signal(signum, _frame):
        sup.request_stop()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGHUP, on_signal)
    sup.start()
    if banner:
        sup.say(banner)
    return sup.run()


def run(args: argparse.Namespace) -> int:
    return launch(args.graph, args.overrides, args.check, args.shutdown_timeout)
