"""Experiment protocol files (``experiments/*.yaml``): schema, loading and validation (no rclpy).

A protocol says which graph runs, the **conditions** (named sets of run-time parameters of its
nodes), the **tasks** (world, start pose, goal region, time limit, instructions) and the
**design** (repetitions, practice, blocks, order). ``experiments/example.yaml`` is the
documented example; docs/experiments.md the reference. Every mistake is reported as one line
``<file>: <key>: <what is wrong and what is allowed>`` before anything starts, like graph files
(the ``graph:`` section *is* a graph file and is validated by :mod:`raspv_bringup.graph`).
"""
from __future__ import annotations

import difflib
import hashlib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from raspv_bringup.graph import Graph, GraphError, graph_from_doc, load_graph, resolve_graph_path
from raspv_bringup.registry import schema_for
from raspv_common import shipped
from raspv_common.text_files import read_text_file
from raspv_experiments.goal_knowledge import KINDS, GoalKnowledge

REPO_ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS_DIR = shipped.EXPERIMENTS_DIR    # the checkout's experiments/, or the installed wheel's copy
ORDERS = ("fixed", "random", "latin_square")
BLOCKS = ("condition", "none")
WITHIN = ("fixed", "random")
_TOP_KEYS = {"name", "description", "graph", "conditions", "tasks", "design", "record", "goal_knowledge"}
_GOAL_KNOWLEDGE_KEYS = {"told", "direction_noise_deg"}
_TASK_KEYS = {"world", "start", "goal", "time_limit", "instructions"}
_DESIGN_KEYS = {"repetitions", "practice", "blocks", "order", "within_block", "seed", "break_between_blocks"}
_RECORD_KEYS = {"bag", "bag_topics", "trajectory_rate"}
DEFAULT_BAG_TOPICS = ("/camera/pose", "/odom", "/cmd_vel", "/head/orientation", "/gaze/direction", "/sim/collisions",
                      "/spv/frame",
                      "/spv/map", "/nav/path")


class ProtocolError(Exception):
    """Mistakes in a protocol file; ``str()`` gives one line per mistake."""

    def __init__(self, errors: list[str]):
        super().__init__("\n".join(errors))
        self.errors = errors


@dataclass(frozen=True)
class Goal:
    """Reached when the avatar's base is within ``radius`` m of (x, y) [m, W]. ``label`` names it
    (an object, a world goal, or the coordinates)."""

    x: float
    y: float
    radius: float
    label: str


@dataclass(frozen=True)
class Task:
    name: str
    world: str                       # as written: shipped world name or path (resolved)
    start_x: float                   # [m, W]
    start_y: float
    start_yaw_deg: float             # [deg], 0 = +x, counter-clockwise
    goal: Goal
    time_limit: float                # [s] of simulation time
    instructions: str


@dataclass(frozen=True)
class Condition:
    name: str
    params: dict[str, dict[str, Any]]    # node name → {parameter: value}
    factors: dict[str, str] = field(default_factory=dict)   # sweeps: factor (NODE.PARAM) → level label


@dataclass(frozen=True)
class Design:
    repetitions: int = 1
    practice: int = 0                    # practice trials at the start of each block
    blocks: str = "condition"            # "condition": one block per condition; "none": one block
    order: str = "fixed"                 # order of the conditions: fixed, random, latin_square
    within_block: str = "fixed"          # order of the trials inside a block: fixed or random
    seed: int = 0
    break_between_blocks: bool = True


@dataclass(frozen=True)
class RecordSpec:
    bag: bool = False
    bag_topics: tuple[str, ...] = DEFAULT_BAG_TOPICS
    trajectory_rate: float = 10.0        # [Hz] of the trial logs


@dataclass
class Protocol:
    path: Path
    name: str
    description: str
    graph: Graph
    conditions: list[Condition]
    tasks: list[Task]
    design: Design
    record: RecordSpec
    goal_knowledge: GoalKnowledge = field(default_factory=GoalKnowledge)   # what virtual patients are told
    text: str = ""                       # the file as written (copied into each session)
    controlled: dict[str, dict[str, Any]] = field(default_factory=dict)   # node → {param: base value}
    factors: dict[str, list[str]] = field(default_factory=dict)   # sweeps: factor → level labels, in order

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()

    def condition(self, name: str) -> Condition:
        return next(c for c in self.conditions if c.name == name)

    def task(self, name: str) -> Task:
        return next(t for t in self.tasks if t.name == name)

    def trial_params(self, condition: str) -> dict[str, dict[str, Any]]:
        """Every parameter any condition sets, at this condition's value or the graph's own (so a
        condition never inherits the previous trial's settings)."""
        chosen = self.condition(condition).params
        return {node: {k: chosen.get(node, {}).get(k, base) for k, base in values.items()}
                for node, values in self.controlled.items()}

    def node_kind(self, node: str) -> str | None:
        return next((n.kind for n in self.graph.nodes if n.name == node), None)


def resolve_protocol_path(name: str) -> Path:
    """A path as given, or the name of a protocol in ``experiments/`` (with or without .yaml)."""
    p = Path(name)
    if p.exists() or p.suffix in (".yaml", ".yml") or "/" in name:
        return p
    return EXPERIMENTS_DIR / f"{name}.yaml"


def _yaml_line(path: Path, exc: yaml.YAMLError) -> str:
    mark = getattr(exc, "problem_mark", None)
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    return f"{path}: {where}invalid YAML ({problem})"


class _Checker:
    """Collects one-line errors ``<file>: <key>: <message>``."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.errors: list[str] = []

    def fail(self, key: str, message: str) -> None:
        self.errors.append(f"{self.path}: {key}: {message}")

    def mapping(self, value: Any, key: str, example: str) -> dict:
        if not isinstance(value, dict):
            self.fail(key, f"expected a mapping, e.g. {example}; got {value!r}")
            return {}
        return value

    def keys(self, value: dict, key: str, allowed: set[str]) -> list[str]:
        """Report each key of ``value`` not in ``allowed`` (with the closest allowed name);
        returns them."""
        unknown = sorted(set(value) - allowed, key=str)
        for k in unknown:
            self.fail(f"{key}.{k}", f"unknown key; allowed: {', '.join(sorted(allowed))}{_did_you_mean(k, allowed)}")
        return unknown

    def number(self, value: Any, key: str, lo: float = -math.inf, hi: float = math.inf, positive: bool = False) -> float:
        rng = "a positive number" if positive else f"a number in [{lo:g}, {hi:g}]"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(key, f"expected {rng}, got {value!r}, which is {_type_name(value)}, not a number")
            return float("nan")
        if not math.isfinite(value) or value < lo or value > hi or (positive and value <= 0):
            self.fail(key, f"expected {rng}, got {value!r}")
            return float("nan")
        return float(value)

    def integer(self, value: Any, key: str, lo: int, hi: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            self.fail(key, f"expected an integer in [{lo}, {hi}], got {value!r}")
            return lo
        return value

    def choice(self, value: Any, key: str, choices: tuple[str, ...]) -> str:
        if value not in choices:
            self.fail(key, f"{value!r} is not allowed; expected one of {', '.join(choices)}")
            return choices[0]
        return value

    def point(self, value: Any, key: str) -> tuple[float, float]:
        if not (isinstance(value, (list, tuple)) and len(value) == 2):
            self.fail(key, f"expected [x, y] in metres, got {value!r}")
            return (float("nan"), float("nan"))
        return (self.number(value[0], key), self.number(value[1], key))


def _did_you_mean(name: Any, allowed: set[str]) -> str:
    close = difflib.get_close_matches(str(name), sorted(allowed), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def _type_name(value: Any) -> str:
    return {str: "text", bool: "true/false", list: "a list", dict: "a mapping", type(None): "empty"}.get(
        type(value), type(value).__name__)


def _positive(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0


def load_protocol(path: str | Path) -> Protocol:
    """Read and validate a protocol file; raise :class:`ProtocolError` listing every mistake."""
    path = Path(path)
    if not path.is_file():
        raise ProtocolError([f"{path}: no such protocol file" + (" (it is a directory)" if path.is_dir() else "")])
    text = read_text_file(path, "protocol file", lambda line: ProtocolError([line]), str(path))
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ProtocolError([_yaml_line(path, exc)]) from None
    return parse_protocol(doc, path, text)


def parse_protocol(doc: Any, path: Path, text: str = "") -> Protocol:
    ck = _Checker(path)
    if not isinstance(doc, dict):
        raise ProtocolError([f"{path}: expected a mapping with graph, conditions, tasks and design"])
    ck.keys(doc, "(top level)", _TOP_KEYS)
    for key in ("graph", "conditions", "tasks"):
        if key not in doc:
            ck.fail(key, "missing; see experiments/example.yaml")
    name = doc.get("name", path.stem)
    if not isinstance(name, str) or not name or any(c in name for c in "/\\ "):
        ck.fail("name", f"expected a name without spaces or slashes, got {name!r}")
        name = path.stem
    description = doc.get("description", "")
    if not isinstance(description, str):
        ck.fail("description", f"expected text, got {description!r}")
        description = ""
    graph = _graph(doc.get("graph"), path, ck)
    conditions = _conditions(doc.get("conditions"), graph, ck)
    tasks = _tasks(doc.get("tasks"), path, ck)
    design = _design(doc.get("design", {}), ck)
    record = _record(doc.get("record", {}), ck)
    knowledge = _goal_knowledge(doc.get("goal_knowledge", {}), ck)
    if ck.errors:
        raise ProtocolError(ck.errors)
    proto = Protocol(path, name, description, graph, conditions, tasks, design, record, knowledge, text)
    proto.controlled = _controlled(proto)
    return proto


def _graph(value: Any, path: Path, ck: _Checker) -> Graph | None:
    if value is None:
        return None
    try:
        if isinstance(value, str):
            local = path.parent / value
            target = local if local.is_file() else resolve_graph_path(value)
            return load_graph(target)
        return graph_from_doc(value, path, where="graph.")
    except GraphError as exc:
        ck.errors.extend(exc.errors)
        return None


def _conditions(value: Any, graph: Graph | None, ck: _Checker) -> list[Condition]:
    out: list[Condition] = []
    if value is None:
        return out
    if not isinstance(value, dict) or not value:
        ck.fail("conditions", "expected a mapping of condition names to node parameters, "
                              "e.g. {depth: {spv: {mode: depth}}}")
        return out
    nodes = {n.name: n.kind for n in graph.nodes} if graph is not None else None
    for cname, body in value.items():
        key = f"conditions.{cname}"
        if not isinstance(cname, str) or not re.fullmatch(r"[A-Za-z0-9_\-=+.]+", cname):
            ck.fail(key, "condition names are letters, digits and _ - = + . (they name files)")
            continue
        body = {} if body is None else ck.mapping(body, key, "{spv: {mode: depth}}")
        params: dict[str, dict[str, Any]] = {}
        for node, values in body.items():
            nkey = f"{key}.{node}"
            values = ck.mapping(values, nkey, "{mode: depth}")
            if nodes is None:
                continue
            if node not in nodes:
                ck.fail(nkey, f"no node named {node!r} in the graph (nodes: {', '.join(nodes)})")
                continue
            schema = schema_for(nodes[node])
            good, bad = schema.validate(values)
            for pkey, message in bad:
                ck.fail(f"{nkey}.{pkey}", message)
            for pkey in good:
                if not schema[pkey].dynamic:
                    ck.fail(f"{nkey}.{pkey}", "cannot change while the graph runs; set it in the graph section")
            params[node] = {k: v for k, v in good.items() if schema[k].dynamic}
        out.append(Condition(cname, params))
    return out


def _goal(value: Any, key: str, world: str, ck: _Checker) -> Goal | None:
    from raspv_sim.world_spec import WorldFileError, load_world

    value = ck.mapping(value, key, "{position: [5, 6], radius: 0.5} or {object: bin, within: 1.0}")
    kinds = [k for k in ("position", "object", "name") if k in value]
    # every mistake at once: unknown keys (a misspelt 'positon' named as such), wrong types
    unknown = ck.keys(value, key, {"position", "radius", "object", "within", "name"})
    for k in ("radius", "within"):
        if k in value:
            ck.number(value[k], f"{key}.{k}", positive=True)
    if len(kinds) != 1:
        if len(kinds) > 1 or not unknown:
            ck.fail(key, "give exactly one of position (with radius), object (with within) or name (a goal of the world)")
        return None
    kind = kinds[0]
    for k in sorted({"radius", "within"} - {"position": {"radius"}, "object": {"within"}, "name": set()}[kind]):
        if k in value:
            ck.fail(f"{key}.{k}", f"applies to a goal given by {'position' if k == 'radius' else 'object'}, not by {kind}")
    if kind == "position":
        x, y = ck.point(value["position"], f"{key}.position")
        r = float(value["radius"]) if _positive(value.get("radius", 0.5)) else 0.5     # else reported above
        return Goal(x, y, r, f"({x:g}, {y:g})")
    try:
        spec = load_world(world)
    except WorldFileError:
        return None                                   # reported by the world check
    target = value[kind]
    if kind == "name":
        goal = next((g for g in spec.goals if g.name == target), None)
        if goal is None:
            known = ", ".join(g.name for g in spec.goals) or "none"
            ck.fail(f"{key}.name", f"{target!r} is not a goal of world {spec.name}; its goals: {known}")
            return None
        return Goal(goal.position[0], goal.position[1], goal.radius, goal.name)
    objects = {o.name: o.position for o in (*spec.furniture, *spec.models)}
    if target not in objects:
        ck.fail(f"{key}.object", f"{target!r} is not an object of world {spec.name}; objects: {', '.join(sorted(objects))}")
        return None
    within = float(value["within"]) if _positive(value.get("within", 1.0)) else 1.0    # else reported above
    pos = objects[target]
    return Goal(float(pos[0]), float(pos[1]), within, str(target))


def _tasks(value: Any, path: Path, ck: _Checker) -> list[Task]:
    from raspv_sim.world_spec import WorldFileError, load_world

    out: list[Task] = []
    if value is None:
        return out
    if not isinstance(value, dict) or not value:
        ck.fail("tasks", "expected a mapping of task names to {world, start, goal, time_limit, instructions}")
        return out
    for tname, body in value.items():
        key = f"tasks.{tname}"
        body = ck.mapping(body, key, "{world: office, start: {position: [1, 6], yaw: 0}, goal: {object: bin}}")
        if not body:
            continue
        ck.keys(body, key, _TASK_KEYS)
        world = body.get("world")
        if not isinstance(world, str) or not world:
            ck.fail(f"{key}.world", f"expected a shipped world name or a world file path, got {world!r}")
            continue
        local = path.parent / world
        world_ref = str(local.resolve()) if local.is_file() else world
        try:
            load_world(world_ref)
        except WorldFileError as exc:
            for line in exc.errors:
                ck.fail(f"{key}.world", line)
            continue
        start = ck.mapping(body.get("start"), f"{key}.start", "{position: [1.0, 6.0], yaw: 0}")
        ck.keys(start, f"{key}.start", {"position", "yaw"})
        sx, sy = (0.0, 0.0)
        if start and "position" not in start:
            ck.fail(f"{key}.start.position", "missing, e.g. position: [1.0, 6.0]")
        elif start:
            sx, sy = ck.point(start["position"], f"{key}.start.position")
        yaw = ck.number(start.get("yaw", 0.0), f"{key}.start.yaw", -360, 360) if start else 0.0
        if start and math.isfinite(sx) and math.isfinite(sy) and math.isfinite(yaw):
            from raspv_experiments.world_geometry import start_problem

            problem = start_problem(world_ref, sx, sy, math.radians(yaw))
            if problem:
                ck.fail(f"{key}.start.position", f"the avatar at [{sx:g}, {sy:g}] {problem}; move the start")
        goal = _goal(body.get("goal"), f"{key}.goal", world_ref, ck)
        limit = ck.number(body.get("time_limit", 60.0), f"{key}.time_limit", positive=True)
        text = body.get("instructions", "")
        if not isinstance(text, str):
            ck.fail(f"{key}.instructions", f"expected text, got {text!r}")
            text = ""
        if goal is not None:
            out.append(Task(str(tname), world_ref, sx, sy, yaw, goal, limit, text.strip()))
    return out


def _design(value: Any, ck: _Checker) -> Design:
    value = ck.mapping(value or {}, "design", "{repetitions: 3, order: latin_square}")
    ck.keys(value, "design", _DESIGN_KEYS)
    d = Design()
    return Design(
        repetitions=ck.integer(value.get("repetitions", d.repetitions), "design.repetitions", 1, 1000),
        practice=ck.integer(value.get("practice", d.practice), "design.practice", 0, 100),
        blocks=ck.choice(value.get("blocks", d.blocks), "design.blocks", BLOCKS),
        order=ck.choice(value.get("order", d.order), "design.order", ORDERS),
        within_block=ck.choice(value.get("within_block", d.within_block), "design.within_block", WITHIN),
        seed=ck.integer(value.get("seed", d.seed), "design.seed", 0, 2**31 - 1),
        break_between_blocks=_bool(value.get("break_between_blocks", d.break_between_blocks),
                                   "design.break_between_blocks", ck))


def _bool(value: Any, key: str, ck: _Checker) -> bool:
    if not isinstance(value, bool):
        ck.fail(key, f"expected true or false, got {value!r}")
        return False
    return value


def _record(value: Any, ck: _Checker) -> RecordSpec:
    value = ck.mapping(value or {}, "record", "{bag: true}")
    ck.keys(value, "record", _RECORD_KEYS)
    topics = value.get("bag_topics", list(DEFAULT_BAG_TOPICS))
    if not (isinstance(topics, list) and topics and all(isinstance(t, str) and t.startswith("/") for t in topics)):
        ck.fail("record.bag_topics", f"expected a list of topic names like /odom, got {topics!r}")
        topics = list(DEFAULT_BAG_TOPICS)
    return RecordSpec(bag=_bool(value.get("bag", False), "record.bag", ck), bag_topics=tuple(topics),
                      trajectory_rate=ck.number(value.get("trajectory_rate", 10.0), "record.trajectory_rate", 0.5, 100))


def _goal_knowledge(value: Any, ck: _Checker) -> GoalKnowledge:
    value = ck.mapping(value or {}, "goal_knowledge", "{told: direction, direction_noise_deg: 30}")
    ck.keys(value, "goal_knowledge", _GOAL_KNOWLEDGE_KEYS)
    told = value.get("told", "exact")
    if told not in KINDS:
        ck.fail("goal_knowledge.told", f"expected one of {', '.join(KINDS)}, got {told!r}")
        told = "exact"
    return GoalKnowledge(told, ck.number(value.get("direction_noise_deg", 30.0), "goal_knowledge.direction_noise_deg",
                                         0.0, 180.0))


def _controlled(proto: Protocol) -> dict[str, dict[str, Any]]:
    """node → {parameter: the graph's value (or the schema default)} for every parameter some
    condition sets."""
    out: dict[str, dict[str, Any]] = {}
    for cond in proto.conditions:
        for node, values in cond.params.items():
            entry = next(n for n in proto.graph.nodes if n.name == node)
            defaults = schema_for(entry.kind).defaults()
            for k in values:
                out.setdefault(node, {})[k] = entry.params.get(k, defaults[k])
    return out


def uses_gaze(protocol: Protocol) -> bool:
    """True when the graph's spv node or a condition sets ``gaze_mode`` other than ``ignored`` (a
    scripted subject then moves its eyes, :mod:`raspv_experiments.scripted_gaze`)."""
    spv = {n.name for n in protocol.graph.nodes if n.kind == "spv"}
    modes = [n.params.get("gaze_mode", "ignored") for n in protocol.graph.nodes if n.kind == "spv"]
    modes += [values.get("gaze_mode", "ignored") for c in protocol.conditions for node, values in c.params.items()
              if node in spv]
    return any(m != "ignored" for m in modes)
