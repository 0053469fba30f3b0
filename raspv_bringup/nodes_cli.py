"""`raspv nodes [KIND]`: the node kinds a graph can run, and their parameters."""
from __future__ import annotations

import argparse

from raspv_bringup.registry import NODES, schema_for


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("kind", nargs="?", help="show the parameters of this node kind")


def run(args: argparse.Namespace) -> int:
    if args.kind is None:
        for kind, spec in sorted(NODES.items()):
            print(f"{kind:<14} {spec.help}")
        return 0
    if args.kind not in NODES:
        print(f"raspv nodes: unknown node kind {args.kind!r}; available: {', '.join(sorted(NODES))}")
        return 2
    for p in schema_for(args.kind):
        unit = f" [{p.unit}]" if p.unit else ""
        flag = "" if p.dynamic else " (fixed at start)"
        names = f"; names a {p.file_kind} file, checked before start" if p.file_kind else ""
        names += f"; {p.pairing()}" if p.pairing() else ""
        print(f"{p.name:<24} = {p.default!r:<14} {p.description}{unit}; {p.allowed()}{names}{flag}")
    return 0
