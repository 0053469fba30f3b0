"""`raspv export-launch GRAPH [NODE.PARAM:=VALUE ...] [-o FILE]`: a graph as a ``ros2 launch`` file.

``--shipped`` rewrites ``launch/<name>.launch.py`` for every graph in ``config/`` (what the
colcon package ``raspv_bringup`` installs; a test checks they match the graphs).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from raspv_bringup.graph import CONFIG_DIR, REPO_ROOT, GraphError, load_graph, resolve_graph_path
from raspv_bringup.launch_export import launch_file_text
from raspv_common.text_files import read_yaml_file

LAUNCH_DIR = REPO_ROOT / "launch"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("graph", nargs="?", help="graph YAML file, or the name of one in config/ (e.g. demo)")
    parser.add_argument("overrides", nargs="*", metavar="NODE.PARAM:=VALUE",
                        help="override a node parameter, e.g. spv.mode:=depth")
    parser.add_argument("-o", "--output", metavar="FILE",
                        help="write here (default: standard output); name it <something>.launch.py")
    parser.add_argument("--shipped", action="store_true",
                        help="rewrite launch/<name>.launch.py for every graph in config/")


def shipped_graphs() -> list[Path]:
    """The graph files in config/ (YAML files with a ``launch:`` section)."""
    return sorted(p for p in CONFIG_DIR.glob("*.yaml") if "launch:" in p.read_text(encoding="utf-8"))


def export(path: Path, overrides: list[str] | None = None, source: str | None = None,
           check_files: bool = True) -> str:
    """The launch file text for the graph at ``path`` (GraphError on a bad graph)."""
    graph = load_graph(path, overrides, check_files=check_files)
    doc = read_yaml_file(path, "graph file", lambda m: GraphError([m]), str(path))
    description = str(doc.get("launch", {}).get("description", "")) if isinstance(doc, dict) else ""
    return launch_file_text(graph, source or str(path), f"{path.stem}.launch.py", description)


def shipped_text(path: Path) -> str:
    """What launch/<name>.launch.py must contain for the config graph ``path``."""
    return export(path, source=f"config/{path.name}", check_files=False)


def run(args: argparse.Namespace) -> int:
    try:
        if args.shipped:
            LAUNCH_DIR.mkdir(exist_ok=True)
            for path in shipped_graphs():
                out = LAUNCH_DIR / f"{path.stem}.launch.py"
                out.write_text(shipped_text(path), encoding="utf-8")
                print(f"raspv export-launch: wrote {out.relative_to(REPO_ROOT)}")
            return 0
        if not args.graph:
            print("raspv export-launch: name a graph (e.g. demo or my_graph.yaml), or --shipped", file=sys.stderr)
            return 2
        path = resolve_graph_path(args.graph)
        text = export(path, args.overrides, source=args.graph)
    except GraphError as exc:
        for line in exc.errors:
            print(f"raspv export-launch: {line}", file=sys.stderr)
        return 2
    if args.output:
        try:
            Path(args.output).write_text(text, encoding="utf-8")
        except OSError as exc:
            print(f"raspv export-launch: {args.output}: {exc.strerror or exc}", file=sys.stderr)
            return 2
        print(f"raspv export-launch: wrote {args.output} (ros2 launch {args.output})")
    else:
        sys.stdout.write(text)
    return 0
