"""MkDocs hook: ``reference/parameters.md``, every node kind's parameters, generated at build
time from the parameter schemas (``raspv_*/*_params.py`` through the node registry), so the
reference cannot drift from the code. The same schemas validate graph files and back
``raspv nodes KIND``."""
from __future__ import annotations

import sys
from pathlib import Path

from mkdocs.structure.files import File

PAGE = "reference/parameters.md"
ROOT = Path(__file__).resolve().parents[2]


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _value(value) -> str:
    return f"`{value!r}`" if value != "" else "`''`"


def parameters_markdown() -> str:
    """The page: a section per node kind, a table row per parameter."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    from raspv_bringup.registry import NODES, schema_for

    out = ["# Node parameters", "",
           "Every parameter of every node kind, generated from the parameter schemas "
           "(`raspv_*/*_params.py`) when the site is built. A graph file sets them under "
           "`<node>: ros__parameters:` ([graph files](../running.md#running-graphs)); "
           "`raspv nodes KIND` prints the same list; *run time* ones change with "
           "`raspv param set NODE NAME VALUE`, the others are fixed at start.", ""]
    out += ["| kind | what it is |", "|---|---|"]
    out += [f"| [{kind}](#{kind}) | {_cell(spec.help)} |" for kind, spec in sorted(NODES.items())]
    for kind, spec in sorted(NODES.items()):
        out += ["", f"## {kind}", "", f"{spec.help}. Node module `{spec.module}`, schema `{spec.params}`.", "",
                "| parameter | default | unit | allowed | changes | description |", "|---|---|---|---|---|---|"]
        for p in schema_for(kind):
            allowed = p.allowed() + (f"; names a {p.file_kind} file, checked before start" if p.file_kind else "")
            allowed += f"; {p.pairing()}" if p.pairing() else ""
            out.append(f"| `{p.name}` | {_cell(_value(p.default))} | {_cell(p.unit)} | {_cell(allowed)} | "
                       f"{'run time' if p.dynamic else 'at start'} | {_cell(p.description)} |")
    return "\n".join(out) + "\n"


def on_files(files, config):
    files.append(File.generated(config, PAGE, content=parameters_markdown()))
    return files
