"""Electrode layouts of real implants, their placement, and where their phosphenes appear (no ROS).

A layout is the set of electrode positions of one device in its own frame (µm). The shipped
layouts are ``config/layouts/<name>.yaml`` (exported from pulse2percept 0.11 by
``tools/layouts/export_pulse2percept_layouts.py``; any YAML file with the same keys is a layout
too); ``neuralink`` is generated here: threads inserted in V1 under a grid of visual-field
positions, as pulse2percept's ``Neuralink.from_visual_field_map``.

Placement is pulse2percept's ``implant_rotation`` then ``implant_position``: the array turns
by ``rotation_deg`` (counter-clockwise in the x-right, y-down tissue frame's own maths) about its
origin, then moves by (x_um, y_um) on the retina (origin at the fovea) or on the cortex map
(:class:`~raspv_spv.retinotopy.WedgeDipoleMap`).

Each electrode's phosphene appears at the visual-field point that maps onto it: the exact
inverse of Watson 2014 eq. A5 on the retina (the peak of the phosphene drawn around it), the
inverse wedge-dipole map on the cortex. The scene is sampled there.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from raspv_common import shipped
from raspv_spv.retinotopy import CORTICAL_MAPS, WedgeDipoleMap, watson_ret_to_dva_exact

LAYOUTS_DIR = shipped.CONFIG_DIR / "layouts"
TARGETS = ("retina", "cortex")
EYES = ("right", "left")
GENERATED = ("neuralink",)

# Neuralink (pulse2percept's factory defaults): a thread under every whole degree of
# x, y in [-3, 3] dva, 32 electrodes 50 µm apart along it, 12 µm off the thread's axis.
NEURALINK_RANGE_DEG = (-3.0, 3.0)
NEURALINK_STEP_DEG = 1.0
NEURALINK_ELECTRODES_PER_THREAD = 32
NEURALINK_AXIS_OFFSET_UM = 12.0


class LayoutError(ValueError):
    """A layout that does not exist or cannot be read."""


@dataclass(frozen=True)
class ElectrodeLayout:
    """Electrodes of one device: ``xy_um`` (N, 2) in its own frame (µm; x right, y down),
    ``names`` (N,), ``radius_um`` (N,), on the ``target`` tissue (retina or cortex)."""

    name: str
    target: str
    names: tuple[str, ...]
    xy_um: np.ndarray = field(repr=False)
    radius_um: np.ndarray = field(repr=False)
    placement: str = ""
    description: str = ""

    @property
    def count(self) -> int:
        return len(self.names)

    def placed(self, x_um: float = 0.0, y_um: float = 0.0, rotation_deg: float = 0.0) -> np.ndarray:
        """Electrode positions (N, 2) µm on the tissue after rotating the array by
        ``rotation_deg`` about its origin and moving it by (``x_um``, ``y_um``)."""
        t = math.radians(rotation_deg)
        c, s = math.cos(t), math.sin(t)
        x, y = self.xy_um[:, 0], self.xy_um[:, 1]
        return np.stack([c * x - s * y + x_um, s * x + c * y + y_um], axis=1)


def layout_names() -> list[str]:
    """Names of the shipped and generated layouts."""
    return sorted({p.stem for p in LAYOUTS_DIR.glob("*.yaml")} | set(GENERATED))


def load_layout(name_or_path: str | Path) -> ElectrodeLayout:
    """A layout by name (``argus_ii``) or from a layout YAML file."""
    text = str(name_or_path).strip()
    if text in GENERATED:
        return neuralink_layout()
    path = Path(text).expanduser()
    if not (path.suffix in (".yaml", ".yml") or "/" in text):
        path = LAYOUTS_DIR / f"{text}.yaml"
        if not path.is_file():
            raise LayoutError(f"unknown implant layout {text!r}; layouts: {', '.join(layout_names())} "
                              "(or the path of a layout YAML file)")
    elif not path.is_file():
        raise LayoutError(f"layout file {path} does not exist")
    return _load_file(str(path.resolve()), path.stat().st_mtime_ns)


@functools.lru_cache(maxsize=32)
def _load_file(path: str, mtime_ns: int) -> ElectrodeLayout:
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise LayoutError(f"{path}: cannot read layout YAML: {exc}".splitlines()[0]) from None
    return layout_from_dict(data, path)


def layout_from_dict(data, source: str = "layout") -> ElectrodeLayout:
    """A layout from a parsed YAML mapping (keys ``name``, ``target``, ``electrodes`` as
    ``[name, x_um, y_um, radius_um]`` rows; optional ``placement``, ``description``)."""
    if not isinstance(data, dict):
        raise LayoutError(f"{source}: expected a mapping with name, target and electrodes")
    missing = [k for k in ("name", "target", "electrodes") if k not in data]
    if missing:
        raise LayoutError(f"{source}: missing key(s) {', '.join(missing)}")
    if data["target"] not in TARGETS:
        raise LayoutError(f"{source}: target must be one of {', '.join(TARGETS)}, got {data['target']!r}")
    rows = data["electrodes"]
    if not isinstance(rows, list) or not rows:
        raise LayoutError(f"{source}: electrodes must be a non-empty list of [name, x_um, y_um, radius_um]")
    names, xy, radius = [], [], []
    for i, row in enumerate(rows):
        if not isinstance(row, (list, tuple)) or len(row) != 4:
            raise LayoutError(f"{source}: electrode {i} must be [name, x_um, y_um, radius_um], got {row!r}")
        try:
            values = [float(v) for v in row[1:]]
        except (TypeError, ValueError):
            raise LayoutError(f"{source}: electrode {i} ({row[0]!r}) has a non-numeric position or radius") from None
        if not all(math.isfinite(v) for v in values) or values[2] < 0:
            raise LayoutError(f"{source}: electrode {i} ({row[0]!r}) needs a finite position and a radius >= 0")
        names.append(str(row[0]))
        xy.append(values[:2])
        radius.append(values[2])
    if len(set(names)) != len(names):
        raise LayoutError(f"{source}: electrode names must be unique")
    xy_arr = np.asarray(xy, dtype=np.float64)
    r_arr = np.asarray(radius, dtype=np.float64)
    for a in (xy_arr, r_arr):
        a.flags.writeable = False
    return ElectrodeLayout(str(data["name"]), data["target"], tuple(names), xy_arr, r_arr,
                           str(data.get("placement", "")), str(data.get("description", "")))


@functools.lru_cache(maxsize=4)
def neuralink_layout(cortical_map: WedgeDipoleMap = CORTICAL_MAPS["polimeni2006"]) -> ElectrodeLayout:
    """Neuralink threads under a grid of visual-field positions (pulse2percept's
    ``Neuralink.from_visual_field_map(LinearEdgeThread, Polimeni2006Map())`` defaults: every
    whole degree in [−3, 3]², a point on the vertical meridian nudged 0.001° to the right).
    One entry per thread: its 32 electrodes lie along the depth of one cortical column, which
    a 2-D map sees as one point, so each thread gives one phosphene. Positions are absolute
    V1 coordinates (no further placement)."""
    lo, hi = NEURALINK_RANGE_DEG
    n = int(round((hi - lo) / NEURALINK_STEP_DEG)) + 1
    ticks = np.linspace(lo, hi, n)
    gx, gy = np.meshgrid(ticks, ticks[::-1], indexing="xy")
    x, y = gx.ravel(), gy.ravel()
    x = np.where(np.isclose(x, 0.0, atol=1e-7), x + math.copysign(1e-3, float(np.mean(x))), x)
    vx, vy = cortical_map.dva_to_v1(x, y)
    keep = np.isfinite(vx) & np.isfinite(vy)
    xy = np.stack([vx[keep] + NEURALINK_AXIS_OFFSET_UM, vy[keep]], axis=1)
    names = tuple(_thread_name(i) for i in range(len(xy)))
    radius = np.full(len(xy), 7.0)
    for a in (xy, radius):
        a.flags.writeable = False
    return ElectrodeLayout("neuralink", "cortex", names, xy, radius, "intracortical",
                           f"Neuralink: {len(xy)} threads of {NEURALINK_ELECTRODES_PER_THREAD} electrodes in V1 under "
                           f"a {NEURALINK_STEP_DEG:g} deg grid over [{lo:g}, {hi:g}]^2 deg (one phosphene per thread)")


def _thread_name(i: int) -> str:
    """A, B, ..., Z, AA, AB, ... (pulse2percept's thread names)."""
    name = ""
    while i >= 26:
        name = chr(65 + i % 26) + name
        i = i // 26 - 1
    return chr(65 + i) + name


def phosphene_positions_deg(target: str, tissue_xy_um: np.ndarray, cortical_map: WedgeDipoleMap | None = None
                            ) -> np.ndarray:
    """Visual-field positions (N, 2) dva where the electrodes at ``tissue_xy_um`` (N, 2) µm make
    their phosphenes appear; NaN where the cortical map has no visual field."""
    xy = np.asarray(tissue_xy_um, dtype=np.float64)
    if target == "retina":
        x, y = watson_ret_to_dva_exact(xy[:, 0], xy[:, 1])
    elif target == "cortex":
        x, y = (cortical_map or CORTICAL_MAPS["polimeni2006"]).v1_to_dva(xy[:, 0], xy[:, 1])
    else:
        raise LayoutError(f"target must be one of {', '.join(TARGETS)}, got {target!r}")
    return np.stack([x, y], axis=1)


@dataclass(frozen=True)
class LayoutSpec:
    """A device layout and its placement: ``layout`` (name or YAML path), rotation
    ``rotation_deg`` about the array's origin then translation (``x_um``, ``y_um``) on the
    tissue, and for cortical layouts the visual-field map (``cortical_map``: polimeni2006 or
    dynaphos)."""

    layout: str
    x_um: float = 0.0
    y_um: float = 0.0
    rotation_deg: float = 0.0
    cortical_map: str = "polimeni2006"

    def __post_init__(self) -> None:
        for name in ("x_um", "y_um", "rotation_deg"):
            if not math.isfinite(getattr(self, name)):
                raise LayoutError(f"implant placement {name} must be finite, got {getattr(self, name)}")
        if self.cortical_map not in CORTICAL_MAPS:
            raise LayoutError(f"cortical_map must be one of {', '.join(CORTICAL_MAPS)}, got {self.cortical_map!r}")


@dataclass(frozen=True)
class PlacedImplant:
    """A layout placed on its tissue, with the electrodes whose phosphenes exist in the visual
    field: ``electrodes_um`` (N, 2) tissue positions, ``centres_deg`` (N, 2) where each
    phosphene appears, ``names`` (N,), and ``left_out`` the names of electrodes the cortical
    map sends nowhere."""

    spec: LayoutSpec
    layout: ElectrodeLayout
    names: tuple[str, ...]
    electrodes_um: np.ndarray = field(repr=False)
    centres_deg: np.ndarray = field(repr=False)
    left_out: tuple[str, ...] = ()

    @property
    def cortical_map(self) -> WedgeDipoleMap:
        return CORTICAL_MAPS[self.spec.cortical_map]

    @classmethod
    def build(cls, spec: LayoutSpec) -> "PlacedImplant":
        layout = load_layout(spec.layout)
        if layout.name == "neuralink" and spec.cortical_map != "polimeni2006":
            layout = neuralink_layout(CORTICAL_MAPS[spec.cortical_map])
        xy = layout.placed(spec.x_um, spec.y_um, spec.rotation_deg)
        deg = phosphene_positions_deg(layout.target, xy, CORTICAL_MAPS[spec.cortical_map])
        ok = np.all(np.isfinite(deg), axis=1) & (np.hypot(deg[:, 0], deg[:, 1]) < 89.0)
        if not ok.any():
            raise LayoutError(f"no electrode of {layout.name} placed at ({spec.x_um:g}, {spec.y_um:g}) µm "
                              f"maps into the visual field")
        names = tuple(n for n, k in zip(layout.names, ok) if k)
        left_out = tuple(n for n, k in zip(layout.names, ok) if not k)
        xy, deg = xy[ok], deg[ok]
        for a in (xy, deg):
            a.flags.writeable = False
        return cls(spec, layout, names, xy, deg, left_out)
