"""World files: the YAML schema, its loader and the precise errors it raises (no pybullet, no rclpy).

A world file describes a building in the world frame W (x, y on the floor, z up, metres; angles in
degrees, counter-clockwise seen from above). :func:`load_world` turns it into a frozen
:class:`WorldSpec`; every mistake raises :class:`WorldFileError` with one line naming the file,
the entry and what is wrong, e.g.
``worlds/x.yaml: furniture[3] (table 'desk'): 'size' must be 3 positive numbers, got [1, 0.8]``.
The format is documented in ``docs/sim.md``.
"""
from __future__ import annotations

import difflib
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from raspv_common.text_files import display_path, read_yaml_file  # noqa: F401 - display_path is re-exported

WORLDS_DIR = Path(__file__).resolve().parent / "worlds"
PYBULLET_DATA_PREFIX = "pybullet_data:"

# Class ids shared by every world (index = id). A world's own labels are appended after these.
BUILTIN_CLASSES: tuple[str, ...] = ("none", "floor", "wall", "door", "stairs", "table", "chair", "sofa",
                                    "bed", "shelf", "bin", "person", "obstacle")
MAX_CLASSES = 256  # labels travel as mono8

FURNITURE_TYPES = ("table", "chair", "sofa", "bed", "shelf", "bin", "door", "box", "cylinder", "rug", "laptop")
FURNITURE_DEFAULT_CLASS = {"box": "obstacle", "cylinder": "obstacle", "rug": "floor"}
# Typical sizes [length along the object's x (its front faces +x), width, height] in metres.
FURNITURE_DEFAULT_SIZE = {
    "table": (1.2, 0.8, 0.75), "chair": (0.45, 0.45, 0.9), "sofa": (0.9, 2.0, 0.85), "bed": (2.0, 1.4, 0.55),
    "shelf": (0.35, 1.0, 1.8), "bin": (0.4, 0.4, 0.6), "door": (0.9, 0.04, 2.05), "box": (0.5, 0.5, 0.5),
    "cylinder": (0.4, 0.4, 1.0), "rug": (2.0, 1.4, 0.01), "laptop": (0.24, 0.34, 0.24),
}
FURNITURE_DEFAULT_COLOR = {
    "table": (0.55, 0.38, 0.22), "chair": (0.35, 0.22, 0.14), "sofa": (0.25, 0.35, 0.55), "bed": (0.45, 0.3, 0.2),
    "shelf": (0.6, 0.45, 0.3), "bin": (0.25, 0.45, 0.3), "door": (0.7, 0.55, 0.38), "box": (0.6, 0.6, 0.62),
    "cylinder": (0.6, 0.6, 0.62), "rug": (0.6, 0.2, 0.2), "laptop": (0.72, 0.73, 0.76),
}
COLOR_NAMES = {
    "white": (0.95, 0.95, 0.95), "black": (0.08, 0.08, 0.08), "grey": (0.5, 0.5, 0.5), "gray": (0.5, 0.5, 0.5),
    "red": (0.8, 0.15, 0.12), "green": (0.2, 0.6, 0.25), "blue": (0.15, 0.3, 0.75), "yellow": (0.9, 0.8, 0.2),
    "orange": (0.9, 0.5, 0.15), "brown": (0.45, 0.3, 0.18), "beige": (0.85, 0.78, 0.65),
}


class WorldFileError(ValueError):
    """A world file that cannot be used. ``errors``: one line per mistake, each naming the file,
    the entry and the fault (a world is checked entry by entry, so every broken entry is
    reported, not only the first); ``str()`` joins them with newlines."""

    def __init__(self, message: str, errors: list[str] | None = None) -> None:
        self.errors = list(errors) if errors else [message]
        super().__init__("\n".join(self.errors))


Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]
Color = tuple[float, float, float]


@dataclass(frozen=True)
class DoorOpening:
    """A gap in a wall: centre ``at`` metres from the wall's start along it, ``width`` × ``height`` m.
    ``leaf`` is the opening angle [deg] of a door leaf in the gap (None: no leaf, 0: closed)."""

    at: float
    width: float
    height: float
    leaf: float | None = None
    hinge: str = "start"     # which side of the gap the leaf hangs on: "start" or "end"
    swing: str = "left"      # the leaf opens towards the wall's left ("left") or right side


@dataclass(frozen=True)
class WallSpec:
    """A straight wall centred on the segment ``start``→``end`` (W, m), extended by half its
    thickness at both ends so corners close."""

    name: str
    cls: str
    start: Vec2
    end: Vec2
    height: float
    thickness: float
    color: Color
    doors: tuple[DoorOpening, ...] = ()
    where: str = ""

    @property
    def length(self) -> float:
        return math.hypot(self.end[0] - self.start[0], self.end[1] - self.start[1])


@dataclass(frozen=True)
class FurnitureSpec:
    """A piece of furniture built from primitives. ``position`` is the centre of its footprint
    (z = height of its base, 0 on the floor); its front faces local +x, turned by ``yaw`` [deg].
    ``size`` = (length along local x, width along local y, height) [m]."""

    name: str
    cls: str
    type: str
    position: Vec3
    yaw: float
    size: Vec3
    color: Color
    specular: bool = False
    open: float = 0.0        # doors only: opening angle [deg] about the hinge at local (0, -w/2)
    shelves: int = 4         # shelves only: number of boards
    where: str = ""


@dataclass(frozen=True)
class ModelSpec:
    """A model from a file: Wavefront OBJ mesh (e.g. exported from Sweet Home 3D), URDF or SDF.
    ``position`` [m] and ``yaw`` [deg] place the file's origin in W; ``scale`` multiplies its units."""

    name: str
    cls: str
    file: Path
    kind: str                # "obj", "urdf" or "sdf"
    position: Vec3
    yaw: float
    scale: float
    color: Color | None
    collision: bool = True
    up: str = "z"            # the file's up axis: "z" (URDF/Bullet) or "y" (many OBJ exporters)
    specular: bool = False
    where: str = ""


@dataclass(frozen=True)
class StairSpec:
    """A straight staircase. ``position`` is the middle of the first step's front edge on the floor;
    ``yaw`` [deg] is the walking direction. ``up``: solid steps rising to a top landing of
    ``landing`` m. ``down``: steps sinking into a well cut into the floor, ending on a bottom landing."""

    name: str
    cls: str
    direction: str           # "up" or "down"
    position: Vec2
    yaw: float
    steps: int
    riser: float
    tread: float
    width: float
    landing: float
    color: Color
    where: str = ""

    @property
    def run(self) -> float:
        """Horizontal extent from the first edge to the far end of the landing [m]."""
        return self.steps * self.tread + self.landing


@dataclass(frozen=True)
class PersonSpec:
    """A person walking a closed loop through ``waypoints`` (W, m) at ``speed`` m/s (kinematic),
    starting ``phase`` metres along the loop. ``model``: "capsule" (primitives) or "humanoid"
    (pybullet_data's humanoid, animated with its walking clip)."""

    name: str
    cls: str
    model: str
    waypoints: tuple[Vec2, ...]
    speed: float
    height: float
    color: Color
    phase: float = 0.0
    where: str = ""


@dataclass(frozen=True)
class GoalSpec:
    """A named place: reached when the avatar's base comes within ``radius`` m of ``position``."""

    name: str
    position: Vec2
    radius: float


@dataclass(frozen=True)
class FloorSpec:
    """The walkable floor: the rectangle ``lo``–``hi`` (W, m) with its top at z = 0."""

    lo: Vec2
    hi: Vec2
    color: Color


@dataclass(frozen=True)
class WorldSpec:
    """A whole world, validated. ``classes[i]`` is the name of class id i."""

    name: str
    source: Path | None
    description: str
    floor: FloorSpec
    walls: tuple[WallSpec, ...]
    furniture: tuple[FurnitureSpec, ...]
    models: tuple[ModelSpec, ...]
    stairs: tuple[StairSpec, ...]
    people: tuple[PersonSpec, ...]
    goals: tuple[GoalSpec, ...]
    spawn_position: Vec2
    spawn_yaw: float
    classes: tuple[str, ...]
    light_direction: Vec3 = (0.4, 0.25, 1.0)

    def class_id(self, name: str) -> int:
        return self.classes.index(name)


# ----------------------------------------------------------------------------------------------
# Reading and checking
# ----------------------------------------------------------------------------------------------

_REQUIRED = object()


def _fmt(value: Any) -> str:
    text = yaml.safe_dump(value, default_flow_style=True, width=10_000).strip()
    text = text[:-4].strip() if text.endswith("\n...") or text.endswith(" ...") else text
    return text if len(text) <= 60 else text[:57] + "..."


def _did_you_mean(key: Any, allowed: set[str]) -> str:
    close = difflib.get_close_matches(str(key), sorted(allowed), n=1, cutoff=0.6)
    return f"; '{key}': did you mean '{close[0]}'?" if close else ""


class _Mistakes:
    """The mistakes of a world file, one per entry: ``with mistakes:`` around one entry's checks
    records its first mistake and goes on with the next entry."""

    def __init__(self) -> None:
        self.errors: list[str] = []

    def __enter__(self) -> "_Mistakes":
        return self

    def __exit__(self, kind, exc, tb) -> bool:
        if isinstance(exc, WorldFileError):
            self.errors.extend(exc.errors)
            return True
        return False


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


class _Entry:
    """One mapping of the world file, with the label used in its error messages."""

    def __init__(self, data: Any, where: str, src: str):
        self.where, self.src = where, src
        if not isinstance(data, dict):
            self.fail(f"expected a mapping of keys, got {_fmt(data)}")
        self.data: dict = data

    def fail(self, problem: str) -> None:
        raise WorldFileError(f"{self.src}: {self.where}: {problem}")

    def keys(self, allowed: set[str]) -> None:
        unknown = [key for key in self.data if key not in allowed]
        if unknown:
            named = ", ".join(f"'{k}'" for k in unknown)
            hints = "".join(_did_you_mean(k, allowed) for k in unknown)
            self.fail(f"unknown key{'s' if len(unknown) > 1 else ''} {named} (allowed: {', '.join(sorted(allowed))}){hints}")

    def get(self, key: str, default: Any = _REQUIRED) -> Any:
        if key in self.data and self.data[key] is not None:
            return self.data[key]
        if default is _REQUIRED:
            self.fail(f"'{key}' is missing")
        return default

    def number(self, key: str, default: Any = _REQUIRED, positive: bool = False, minimum: float | None = None,
               maximum: float | None = None) -> float:
        v = self.get(key, default)
        if not _is_number(v):
            self.fail(f"'{key}' must be a number, got {_fmt(v)}")
        if positive and v <= 0:
            self.fail(f"'{key}' must be positive, got {_fmt(v)}")
        if minimum is not None and v < minimum:
            self.fail(f"'{key}' must be at least {minimum}, got {_fmt(v)}")
        if maximum is not None and v > maximum:
            self.fail(f"'{key}' must be at most {maximum}, got {_fmt(v)}")
        return float(v)

    def integer(self, key: str, default: Any = _REQUIRED, minimum: int = 1, maximum: int = 10_000) -> int:
        v = self.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int) or not minimum <= v <= maximum:
            self.fail(f"'{key}' must be a whole number in [{minimum}, {maximum}], got {_fmt(v)}")
        return int(v)

    def vector(self, key: str, sizes: tuple[int, ...], default: Any = _REQUIRED, positive: bool = False) -> tuple:
        v = self.get(key, default)
        ok = isinstance(v, (list, tuple)) and len(v) in sizes and all(_is_number(x) for x in v)
        if ok and positive:
            ok = all(x > 0 for x in v)
        if not ok:
            count = " or ".join(str(s) for s in sizes)
            self.fail(f"'{key}' must be {count} {'positive ' if positive else ''}numbers, got {_fmt(v)}")
        return tuple(float(x) for x in v)

    def string(self, key: str, default: Any = _REQUIRED, choices: tuple[str, ...] | None = None) -> str:
        v = self.get(key, default)
        if not isinstance(v, str) or not v.strip():
            self.fail(f"'{key}' must be a non-empty string, got {_fmt(v)}")
        if choices is not None and v not in choices:
            self.fail(f"'{key}' must be one of {', '.join(choices)}, got {_fmt(v)}")
        return v.strip()

    def boolean(self, key: str, default: bool) -> bool:
        v = self.get(key, default)
        if not isinstance(v, bool):
            self.fail(f"'{key}' must be true or false, got {_fmt(v)}")
        return v

    def color(self, key: str, default: Color | None) -> Color | None:
        v = self.get(key, default)
        if v is None or (isinstance(v, tuple) and v == default):
            return v
        if isinstance(v, str):
            name = v.strip().lower()
            if name in COLOR_NAMES:
                return COLOR_NAMES[name]
            if re.fullmatch(r"#[0-9a-f]{6}", name):
                return tuple(int(name[i:i + 2], 16) / 255.0 for i in (1, 3, 5))  # type: ignore[return-value]
        elif isinstance(v, (list, tuple)) and len(v) == 3 and all(_is_number(x) and 0 <= x <= 1 for x in v):
            return tuple(float(x) for x in v)  # type: ignore[return-value]
        self.fail(f"'{key}' must be [r, g, b] in 0..1, '#rrggbb' or one of {', '.join(COLOR_NAMES)}; got {_fmt(v)}")
        return None

    def sequence(self, key: str) -> list:
        v = self.get(key, [])
        if not isinstance(v, list):
            self.fail(f"'{key}' must be a list, got {_fmt(v)}")
        return v


def resolve_world_path(world: str | Path) -> Path:
    """A shipped world's name (``apartment``) or a path to a YAML file → the file's path."""
    text = str(world).strip()
    if not text:
        raise WorldFileError("no world given: name a shipped world (" + ", ".join(shipped_worlds()) + ") or a YAML file")
    candidate = Path(text).expanduser()
    if candidate.suffix in (".yaml", ".yml") or os.sep in text or candidate.exists():
        if candidate.is_dir():
            raise WorldFileError(f"{text}: is a directory, not a world file")
        if not candidate.is_file():
            raise WorldFileError(f"{text}: no such world file")
        return candidate.resolve()
    shipped = WORLDS_DIR / f"{text}.yaml"
    if shipped.is_file():
        return shipped
    raise WorldFileError(f"unknown world '{text}': shipped worlds are {', '.join(shipped_worlds())}, "
                         "or give the path of a YAML file")


def shipped_worlds() -> list[str]:
    return sorted(p.stem for p in WORLDS_DIR.glob("*.yaml"))


def load_world(world: str | Path) -> WorldSpec:
    """Read and validate a world (shipped name or path). Raises :class:`WorldFileError`."""
    path = resolve_world_path(world)
    src = display_path(path)
    data = read_yaml_file(path, "world file", WorldFileError, src)
    return parse_world(data, src, path)


def parse_world(data: Any, src: str = "<world>", path: Path | None = None) -> WorldSpec:
    """Validate the parsed YAML ``data`` of a world file (``src`` labels the errors). Every entry
    is checked; :class:`WorldFileError` lists the first mistake of each broken entry."""
    top = _Entry(data, "top level", src)
    mistakes = _Mistakes()
    with mistakes:
        top.keys({"name", "description", "floor", "defaults", "rooms", "walls", "furniture", "models", "stairs",
                  "people", "goals", "spawn", "light"})
    base_dir = path.parent if path is not None else Path.cwd()
    classes: list[str] = list(BUILTIN_CLASSES)
    names: dict[str, str] = {}

    def claim(name: str, where: str, entry: _Entry) -> None:
        if name in names:
            entry.fail(f"name '{name}' is already used by {names[name]}")
        names[name] = where

    def label(entry: _Entry, default: str) -> str:
        cls = entry.string("class", default)
        if cls not in classes:
            if len(classes) >= MAX_CLASSES:
                entry.fail(f"too many classes (at most {MAX_CLASSES - len(BUILTIN_CLASSES)} besides the built-in ones)")
            classes.append(cls)
        return cls

    name, description = path.stem if path is not None else "world", ""
    with mistakes:
        name = top.string("name", name)
    with mistakes:
        description = top.get("description", "")
        if not isinstance(description, str):
            top.fail(f"'description' must be a string, got {_fmt(description)}")

    wall_height, wall_thickness, wall_color, door_height = 2.5, 0.12, (0.88, 0.86, 0.8), 2.05
    with mistakes:
        d = _Entry(top.get("defaults", {}), "defaults", src)
        d.keys({"wall_height", "wall_thickness", "wall_color", "door_height"})
        wall_height = d.number("wall_height", wall_height, positive=True)
        wall_thickness = d.number("wall_thickness", wall_thickness, positive=True)
        wall_color = d.color("wall_color", wall_color)
        door_height = d.number("door_height", door_height, positive=True)

    floor: FloorSpec | None = None
    with mistakes:
        f = _Entry(top.get("floor"), "floor", src)
        f.keys({"from", "to", "color"})
        lo, hi = f.vector("from", (2,)), f.vector("to", (2,))
        if not (hi[0] > lo[0] and hi[1] > lo[1]):
            f.fail(f"'to' {list(hi)} must be above and right of 'from' {list(lo)} (x and y larger)")
        floor = FloorSpec(lo, hi, f.color("color", (0.72, 0.66, 0.58)))

    def parse_doors(entry: _Entry, length: float, height: float) -> tuple[DoorOpening, ...]:
        doors = []
        for j, raw in enumerate(entry.sequence("doors")):
            de = _Entry(raw, f"{entry.where}: doors[{j}]", src)
            de.keys({"at", "width", "height", "leaf", "hinge", "swing"})
            at, width = de.number("at"), de.number("width", 0.9, positive=True)
            h = de.number("height", min(door_height, height), positive=True)
            if at - width / 2 < -1e-9 or at + width / 2 > length + 1e-9:
                de.fail(f"the opening [{at - width / 2:g}, {at + width / 2:g}] m does not fit in the wall (length {length:g} m)")
            if h > height + 1e-9:
                de.fail(f"'height' {h:g} m is taller than the wall ({height:g} m)")
            leaf = de.get("leaf", None)
            if leaf is not None:
                leaf = de.number("leaf", minimum=0.0, maximum=180.0)
            doors.append(DoorOpening(at, width, h, leaf, de.string("hinge", "start", ("start", "end")),
                                     de.string("swing", "left", ("left", "right"))))
        doors.sort(key=lambda o: o.at)
        for a, b in zip(doors, doors[1:]):
            if a.at + a.width / 2 > b.at - b.width / 2 + 1e-9:
                entry.fail(f"door openings at {a.at:g} m and {b.at:g} m overlap")
        return tuple(doors)

    walls: list[WallSpec] = []
    for i, raw in enumerate(_sequence(top, "rooms", mistakes)):
        with mistakes:
            e = _Entry(raw, f"rooms[{i}]", src)
            rname = e.string("name", f"room{i}")
            e.where = f"rooms[{i}] ('{rname}')"
            e.keys({"name", "from", "to", "height", "thickness", "color", "doors", "open", "class"})
            rlo, rhi = e.vector("from", (2,)), e.vector("to", (2,))
            if not (rhi[0] > rlo[0] and rhi[1] > rlo[1]):
                e.fail(f"'to' {list(rhi)} must be above and right of 'from' {list(rlo)} (x and y larger)")
            height = e.number("height", wall_height, positive=True)
            thick = e.number("thickness", wall_thickness, positive=True)
            color = e.color("color", wall_color)
            cls = label(e, "wall")
            sides = {"south": ((rlo[0], rlo[1]), (rhi[0], rlo[1])), "east": ((rhi[0], rlo[1]), (rhi[0], rhi[1])),
                     "north": ((rlo[0], rhi[1]), (rhi[0], rhi[1])), "west": ((rlo[0], rlo[1]), (rlo[0], rhi[1]))}
            open_sides = e.get("open", [])
            if not isinstance(open_sides, list) or any(s not in sides for s in open_sides):
                e.fail(f"'open' must be a list of sides (south, east, north, west), got {_fmt(open_sides)}")
            side_doors: dict[str, list] = {s: [] for s in sides}
            for j, raw_door in enumerate(e.sequence("doors")):
                de = _Entry(raw_door, f"{e.where}: doors[{j}]", src)
                side = de.string("wall", choices=tuple(sides))
                if side in open_sides:
                    de.fail(f"side '{side}' is open, it has no wall to put a door in")
                side_doors[side].append({k: v for k, v in raw_door.items() if k != "wall"})
            for side, (a, b) in sides.items():
                if side in open_sides:
                    continue
                wname = f"{rname}/{side}"
                claim(wname, e.where, e)
                length = math.hypot(b[0] - a[0], b[1] - a[1])
                sub = _Entry({"doors": side_doors[side]}, f"{e.where}: {side} wall", src)
                walls.append(WallSpec(wname, cls, a, b, height, thick, color, parse_doors(sub, length, height), e.where))

    for i, raw in enumerate(_sequence(top, "walls", mistakes)):
        with mistakes:
            e = _Entry(raw, f"walls[{i}]", src)
            wname = e.string("name", f"wall{i}")
            e.where = f"walls[{i}] ('{wname}')"
            e.keys({"name", "from", "to", "height", "thickness", "color", "doors", "class"})
            a, b = e.vector("from", (2,)), e.vector("to", (2,))
            length = math.hypot(b[0] - a[0], b[1] - a[1])
            if length < 1e-6:
                e.fail("'from' and 'to' are the same point")
            height = e.number("height", wall_height, positive=True)
            claim(wname, e.where, e)
            walls.append(WallSpec(wname, label(e, "wall"), a, b, height, e.number("thickness", wall_thickness, positive=True),
                                  e.color("color", wall_color), parse_doors(e, length, height), e.where))

    furniture: list[FurnitureSpec] = []
    for i, raw in enumerate(_sequence(top, "furniture", mistakes)):
        with mistakes:
            e = _Entry(raw, f"furniture[{i}]", src)
            kind = e.string("type", choices=FURNITURE_TYPES)
            e.where = f"furniture[{i}] ({kind})"
            fname = e.string("name", f"{kind}{i}")
            if "name" in e.data:
                e.where = f"furniture[{i}] ({kind} '{fname}')"
            e.keys({"type", "name", "position", "yaw", "size", "color", "class", "specular", "open", "shelves"})
            pos = e.vector("position", (2, 3))
            size = e.vector("size", (3,), FURNITURE_DEFAULT_SIZE[kind], positive=True)
            claim(fname, e.where, e)
            furniture.append(FurnitureSpec(
                fname, label(e, FURNITURE_DEFAULT_CLASS.get(kind, kind)), kind, (pos[0], pos[1], pos[2] if len(pos) == 3 else 0.0),
                e.number("yaw", 0.0), size, e.color("color", FURNITURE_DEFAULT_COLOR[kind]), e.boolean("specular", False),
                e.number("open", 0.0, minimum=-180.0, maximum=180.0) if kind == "door" else 0.0,
                e.integer("shelves", 4, minimum=1, maximum=20) if kind == "shelf" else 4, e.where))
            if kind != "door" and "open" in e.data:
                e.fail("'open' applies to doors only")
            if kind != "shelf" and "shelves" in e.data:
                e.fail("'shelves' applies to shelves only")

    models: list[ModelSpec] = []
    for i, raw in enumerate(_sequence(top, "models", mistakes)):
        with mistakes:
            e = _Entry(raw, f"models[{i}]", src)
            mname = e.string("name", f"model{i}")
            e.where = f"models[{i}] ('{mname}')"
            e.keys({"name", "file", "position", "yaw", "scale", "color", "class", "collision", "up", "specular"})
            file_text = e.string("file")
            fpath = _resolve_model_file(file_text, base_dir)
            kind = fpath.suffix.lower().lstrip(".")
            if kind not in ("obj", "urdf", "sdf"):
                e.fail(f"'file' must be an .obj mesh, a .urdf or an .sdf model, got '{file_text}'")
            if not fpath.is_file():
                e.fail(f"'file' {file_text} not found (looked at {fpath})")
            pos = e.vector("position", (2, 3), (0.0, 0.0, 0.0))
            claim(mname, e.where, e)
            models.append(ModelSpec(mname, label(e, "obstacle"), fpath, kind,
                                    (pos[0], pos[1], pos[2] if len(pos) == 3 else 0.0), e.number("yaw", 0.0),
                                    e.number("scale", 1.0, positive=True), e.color("color", None),
                                    e.boolean("collision", True), e.string("up", "z", ("z", "y")),
                                    e.boolean("specular", False), e.where))

    stairs: list[StairSpec] = []
    for i, raw in enumerate(_sequence(top, "stairs", mistakes)):
        with mistakes:
            e = _Entry(raw, f"stairs[{i}]", src)
            sname = e.string("name", f"stairs{i}")
            e.where = f"stairs[{i}] ('{sname}')"
            e.keys({"name", "direction", "position", "yaw", "steps", "riser", "tread", "width", "landing", "color", "class"})
            direction = e.string("direction", choices=("up", "down"))
            riser = e.number("riser", 0.17, positive=True, maximum=0.5)
            steps = e.integer("steps", 8, minimum=1, maximum=100)
            yaw = e.number("yaw", 0.0)
            if direction == "down" and abs(yaw / 90.0 - round(yaw / 90.0)) > 1e-9:
                e.fail(f"a descending staircase's 'yaw' must be a multiple of 90 degrees (its well is cut along x and y), got {yaw:g}")
            claim(sname, e.where, e)
            stairs.append(StairSpec(sname, label(e, "stairs"), direction, e.vector("position", (2,)), yaw,
                                    steps, riser, e.number("tread", 0.29, positive=True), e.number("width", 1.2, positive=True),
                                    e.number("landing", 1.2, minimum=0.0), e.color("color", (0.78, 0.76, 0.72)), e.where))

    people: list[PersonSpec] = []
    for i, raw in enumerate(_sequence(top, "people", mistakes)):
        with mistakes:
            e = _Entry(raw, f"people[{i}]", src)
            pname = e.string("name", f"person{i}")
            e.where = f"people[{i}] ('{pname}')"
            e.keys({"name", "model", "waypoints", "speed", "height", "color", "class", "phase"})
            wps = e.get("waypoints")
            if not (isinstance(wps, list) and len(wps) >= 2 and all(
                    isinstance(w, (list, tuple)) and len(w) == 2 and all(_is_number(x) for x in w) for w in wps)):
                e.fail(f"'waypoints' must be a list of at least 2 [x, y] points, got {_fmt(wps)}")
            pts = tuple((float(w[0]), float(w[1])) for w in wps)
            if sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(pts, pts[1:] + pts[:1])) < 1e-6:
                e.fail("'waypoints' are all the same point")
            claim(pname, e.where, e)
            people.append(PersonSpec(pname, label(e, "person"), e.string("model", "capsule", ("capsule", "humanoid")), pts,
                                     e.number("speed", 1.0, minimum=0.0, maximum=5.0),
                                     e.number("height", 1.75, minimum=0.5, maximum=2.5),
                                     e.color("color", (0.75, 0.2, 0.2)), e.number("phase", 0.0, minimum=0.0), e.where))

    goals: list[GoalSpec] = []
    for i, raw in enumerate(_sequence(top, "goals", mistakes)):
        with mistakes:
            e = _Entry(raw, f"goals[{i}]", src)
            e.keys({"name", "position", "radius"})
            gname = e.string("name")
            e.where = f"goals[{i}] ('{gname}')"
            if any(g.name == gname for g in goals):
                e.fail(f"goal name '{gname}' is used twice")
            goals.append(GoalSpec(gname, e.vector("position", (2,)), e.number("radius", 0.6, positive=True)))

    spawn, spawn_yaw = (0.0, 0.0), 0.0
    with mistakes:
        s = _Entry(top.get("spawn"), "spawn", src)
        s.keys({"position", "yaw"})
        spawn = s.vector("position", (2,))
        if floor is not None and not (floor.lo[0] < spawn[0] < floor.hi[0] and floor.lo[1] < spawn[1] < floor.hi[1]):
            s.fail(f"'position' {list(spawn)} is outside the floor {list(floor.lo)}..{list(floor.hi)}")
        spawn_yaw = s.number("yaw", 0.0)

    light_dir = (0.4, 0.25, 1.0)
    with mistakes:
        light = _Entry(top.get("light", {}), "light", src)
        light.keys({"direction"})
        light_dir = light.vector("direction", (3,), light_dir)
        if math.hypot(*light_dir) < 1e-9:
            light.fail("'direction' must not be zero")

    if mistakes.errors or floor is None:
        raise WorldFileError(mistakes.errors[0], mistakes.errors)
    return WorldSpec(name, path, description, floor, tuple(walls), tuple(furniture), tuple(models), tuple(stairs),
                     tuple(people), tuple(goals), spawn, spawn_yaw, tuple(classes), light_dir)


def _sequence(top: _Entry, key: str, mistakes: _Mistakes) -> list:
    """The list under ``key`` of the top level ([] when it is not a list: a mistake recorded)."""
    with mistakes:
        return top.sequence(key)
    return []


def _resolve_model_file(text: str, base_dir: Path) -> Path:
    if text.startswith(PYBULLET_DATA_PREFIX):
        import pybullet_data

        return Path(pybullet_data.getDataPath()) / text[len(PYBULLET_DATA_PREFIX):]
    p = Path(text).expanduser()
    return p if p.is_absolute() else (base_dir / p).resolve()
