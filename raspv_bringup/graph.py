"""Graph files: a standard ROS 2 parameter file plus a ``launch:`` section (no rclpy).

```yaml
launch:
  env: {KEY: value}              # optional, extra environment for every node
  nodes:
    - kind: sim                  # node kind, see `raspv nodes`
      name: sim                  # optional, node name (default: the kind)
      restart: false             # optional, restart it when it dies instead of stopping the graph
      spare: true                # optional (default: as restart), keep a warm spare process for restarts
    - kind: spv
sim:
  ros__parameters: {world: apartment}
spv:
  ros__parameters: {device: default, mode: grey}
```

Everything is checked before any process starts; every mistake is reported as
``<file>: <key>: <what is wrong and what is allowed>``.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from raspv_bringup.file_kinds import check_files as check_named_files
from raspv_bringup.registry import NODES, schema_for
from raspv_common import shipped
from raspv_common.text_files import read_yaml_file

REPO_ROOT = Path(__file__).resolve().parents[1]
CONFIG_DIR = shipped.CONFIG_DIR    # the checkout's config/, or the installed wheel's copy
_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_NODE_KEYS = {"kind", "name", "restart", "spare", "env"}
GLOBAL_PARAMS = {"use_sim_time": False}  # accepted for every node (ROS built-in)
IMAGE_SOURCES = ("sim", "camera", "replay", "synthetic")   # node kinds publishing the camera images


class GraphError(Exception):
    """One or more mistakes in a graph file; ``str()`` gives one line per mistake."""

    def __init__(self, errors: list[str]):
        super().__init__("\n".join(errors))
        self.errors = errors


@dataclass
class NodeEntry:
    kind: str
    name: str
    restart: bool
    params: dict[str, Any]
    env: dict[str, str] = field(default_factory=dict)
    spare: bool = False        # keep a warm spare process to restart from (raspv_bringup/warm_spare.py)

    @property
    def module(self) -> str:
        return NODES[self.kind].module


@dataclass
class Graph:
    path: Path
    nodes: list[NodeEntry]
    env: dict[str, str]

    def node(self, name: str) -> NodeEntry:
        return next(n for n in self.nodes if n.name == name)


def resolve_graph_path(name: str) -> Path:
    """A path as given, or the name of a file in ``config/`` (with or without ``.yaml``)."""
    p = Path(name)
    if p.exists() or p.suffix in (".yaml", ".yml") or os.sep in name:
        return p
    return CONFIG_DIR / f"{name}.yaml"


def parse_override(text: str) -> tuple[str, str, Any]:
    """``node.param:=value`` (value parsed as YAML) → (node, param, value)."""
    if ":=" not in text or "." not in text.split(":=", 1)[0]:
        raise GraphError([f"override {text!r}: expected NODE.PARAM:=VALUE, e.g. spv.mode:=depth"])
    key, raw = text.split(":=", 1)
    node, param = key.split(".", 1)
    try:
        value = yaml.safe_load(raw) if raw != "" else ""
    except yaml.YAMLError:
        value = raw
    return node, param, value


def load_graph(path: str | Path, overrides: list[str] | None = None, check_files: bool = True) -> Graph:
    """Read and validate a graph file; raise :class:`GraphError` listing every mistake.
    With ``check_files``, every file a parameter names (worlds and their meshes, devices,
    maps, bags, …; see :mod:`raspv_bringup.file_kinds`) is checked too."""
    path = Path(path)
    if not path.is_file():
        raise GraphError([f"{path}: no such graph file" + (" (it is a directory)" if path.is_dir() else "")])
    doc = read_yaml_file(path, "graph file", lambda message: GraphError([message]), str(path))
    return graph_from_doc(doc, path, overrides, check_files=check_files)


def graph_from_doc(doc: Any, path: str | Path, overrides: list[str] | None = None, where: str = "",
                   check_files: bool = True) -> Graph:
    """Validate a graph already read from YAML (e.g. the ``graph:`` section of an experiment
    protocol); ``where`` prefixes the keys in messages (``"graph."``)."""
    path = Path(path)
    if not isinstance(doc, dict):
        raise GraphError([f"{path}: {where or ''}expected a mapping with a 'launch' section and node parameter sections"])
    if where:
        return _prefixed(doc, path, overrides, where, check_files)
    errors: list[str] = []
    launch = doc.get("launch")
    if not isinstance(launch, dict) or not isinstance(launch.get("nodes"), list) or not launch["nodes"]:
        raise GraphError([f"{path}: launch.nodes: expected a non-empty list of nodes, e.g. [{{kind: spv}}]"])
    unknown = set(launch) - {"nodes", "env", "description"}
    for k in sorted(unknown):
        errors.append(f"{path}: launch.{k}: unknown key; allowed: nodes, env, description")
    env = _string_map(launch.get("env", {}), f"{path}: launch.env", errors)

    nodes: list[NodeEntry] = []
    seen: set[str] = set()
    for i, item in enumerate(launch["nodes"]):
        where = f"{path}: launch.nodes[{i}]"
        if isinstance(item, str):
            item = {"kind": item}
        if not isinstance(item, dict):
            errors.append(f"{where}: expected a mapping like {{kind: spv}}, got {item!r}")
            continue
        for k in sorted(set(item) - _NODE_KEYS):
            errors.append(f"{where}.{k}: unknown key; allowed: {', '.join(sorted(_NODE_KEYS))}")
        kind = item.get("kind")
        if kind not in NODES:
            errors.append(f"{where}.kind: unknown node kind {kind!r}; available: {', '.join(sorted(NODES))}")
            continue
        name = item.get("name", kind)
        if not isinstance(name, str) or not _NAME_RE.match(name):
            errors.append(f"{where}.name: {name!r} is not a valid node name (letters, digits, underscores)")
            continue
        if name in seen:
            errors.append(f"{where}.name: node name {name!r} used twice")
            continue
        seen.add(name)
        restart = item.get("restart", False)
        if not isinstance(restart, bool):
            errors.append(f"{where}.restart: expected true or false, got {restart!r}")
            restart = False
        spare = item.get("spare", restart)
        if not isinstance(spare, bool):
            errors.append(f"{where}.spare: expected true or false, got {spare!r}")
            spare = False
        nodes.append(NodeEntry(kind, name, restart, {}, _string_map(item.get("env", {}), f"{where}.env", errors),
                               spare=spare and restart))

    by_name = {n.name: n for n in nodes}
    sections: dict[str, dict[str, Any]] = {}
    global_params: dict[str, Any] = {}
    for key, section in doc.items():
        if key == "launch":
            continue
        where = f"{path}: {key}"
        if not isinstance(section, dict) or set(section) != {"ros__parameters"} or not isinstance(section["ros__parameters"], dict):
            errors.append(f"{where}: expected '{key}: {{ros__parameters: {{...}}}}'")
            continue
        if key in ("/**", "**"):
            global_params = section["ros__parameters"]
            continue
        name = key.lstrip("/")
        if name not in by_name:
            errors.append(f"{where}: no node named {name!r} in launch.nodes (nodes: {', '.join(by_name) or 'none'})")
            continue
        sections[name] = dict(section["ros__parameters"])

    for ov in overrides or []:
        try:
            node, param, value = parse_override(ov)
        except GraphError as exc:
            errors.extend(exc.errors)
            continue
        if node not in by_name:
            errors.append(f"override {ov!r}: no node named {node!r} (nodes: {', '.join(by_name)})")
            continue
        sections.setdefault(node, {})[param] = value

    checked: dict[tuple, str | None] = {}               # file checks by (kind, value), done once
    for node in nodes:
        schema = schema_for(node.kind)
        for gk, gv in global_params.items():
            if gk in GLOBAL_PARAMS:
                node.params[gk] = gv
            elif gk in schema:
                node.params.setdefault(gk, gv)
        values = dict(sections.get(node.name, {}))
        builtin = {k: values.pop(k) for k in list(values) if k in GLOBAL_PARAMS}
        good, bad = schema.validate(values)
        for key, message in bad + schema.check_together({**node.params, **good}):
            errors.append(f"{path}: {node.name}.ros__parameters.{key}: {message}")
        if check_files:
            for key, message in check_named_files(schema, {**node.params, **good}, checked):
                errors.append(f"{path}: {node.name}.ros__parameters.{key}: {message}")
        for k, v in builtin.items():
            if not isinstance(v, bool):
                errors.append(f"{path}: {node.name}.ros__parameters.{k}: expected true or false, got {v!r}")
        node.params.update(builtin)
        node.params.update(good)
    _set_camera_source(nodes, sections, path, errors)
    _set_rolling_shutter(nodes, sections)
    for gk in global_params:
        if gk not in GLOBAL_PARAMS and not any(gk in schema_for(n.kind) for n in nodes):
            errors.append(f"{path}: /**.ros__parameters.{gk}: no node in this graph has this parameter")
    if errors:
        raise GraphError(errors)
    return Graph(path=path, nodes=nodes, env=env)


def _set_camera_source(nodes: list[NodeEntry], sections: dict[str, dict[str, Any]], path: Path,
                       errors: list[str]) -> None:
    """Set every spv node's ``camera_source`` from the graph's image source (the first of
    :data:`IMAGE_SOURCES`; the scene node's ``mounting`` for a live camera), so that the viewer's
    head never turns a recorded or hand-held camera (:mod:`raspv_spv.camera_source`). A graph
    without a source leaves the spv node's own value (default ``unknown``: not turned)."""
    from raspv_spv.camera_source import camera_source_of

    source = next((n for n in nodes if n.kind in IMAGE_SOURCES), None)
    if source is None:
        return
    mounting = next((n.params.get("mounting", "head") for n in nodes if n.kind == "scene"), "head")
    file = str(source.params.get("file", "") or "")
    derived = camera_source_of(source.kind, file, mounting)
    what = {"sim": "the simulator's head camera", "recording": f"a recording ({source.name} node)"}.get(
        derived, f"a live camera carried on the {mounting} (scene.mounting)")
    for node in nodes:
        if node.kind != "spv":
            continue
        given = sections.get(node.name, {}).get("camera_source")
        if given is not None and given != derived:
            errors.append(f"{path}: {node.name}.ros__parameters.camera_source: {given!r}, but the images come from "
                          f"{what}: {derived!r} (set by the launcher; leave it out)")
        node.params["camera_source"] = derived


def _set_rolling_shutter(nodes: list[NodeEntry], sections: dict[str, dict[str, Any]]) -> None:
    """Give every slam node that was not given ``rolling_shutter_readout`` the readout the replayed
    bag carries (:func:`raspv_bags.camera_metadata.recorded_rolling_shutter`: ``raspv bag
    from-frames --camera tum-fr1`` keeps its preset's), as ROS camera info cannot carry it."""
    source = next((n for n in nodes if n.kind in IMAGE_SOURCES), None)
    if source is None or source.kind != "replay" or not source.params.get("bag"):
        return
    from raspv_bags.camera_metadata import recorded_rolling_shutter

    readout = recorded_rolling_shutter(str(source.params["bag"]))
    if readout is None:
        return
    for node in nodes:
        if node.kind == "slam" and "rolling_shutter_readout" not in sections.get(node.name, {}):
            node.params["rolling_shutter_readout"] = readout


def _prefixed(doc: dict, path: Path, overrides: list[str] | None, where: str, check_files: bool) -> Graph:
    """graph_from_doc with every message's key prefixed by ``where``."""
    try:
        return graph_from_doc(doc, path, overrides, check_files=check_files)
    except GraphError as exc:
        head = f"{path}: "
        raise GraphError([head + where + e[len(head):] if e.startswith(head) else e for e in exc.errors]) from None


def _string_map(value: Any, where: str, errors: list[str]) -> dict[str, str]:
    if value in (None, {}):
        return {}
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        errors.append(f"{where}: expected a mapping of NAME: value")
        return {}
    return {k: str(v) for k, v in value.items()}


def node_params_file(node: NodeEntry) -> str:
    """The ROS 2 parameter file text for one node (only its own section)."""
    return yaml.safe_dump({node.name: {"ros__parameters": node.params}}, sort_keys=True)
