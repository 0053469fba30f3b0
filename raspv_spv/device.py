"""Device presets: the parameters of a simulated prosthesis, from YAML (no ROS).

Presets ship in ``config/devices/<name>.yaml`` (the paper's default, argus_ii, argus_iii,
alpha_ims, optimist, and real implant layouts with literature sprite models: argus_ii_axon,
alpha_ims_layout, prima, bva44, orion, icvp, neuralink …); any YAML file with the same keys is a
device too. Unknown keys, missing keys and impossible values are reported with the file name
and what is allowed.

A device either spreads ``num_phosphenes`` on the paper's lattice (``grid``, ``field``), or
names an implant ``layout`` (:mod:`raspv_spv.implant_layout`) placed at ``implant_x_um``,
``implant_y_um``, ``implant_rotation_deg`` on the retina or cortex (``eye``, ``cortical_map``);
either way ``sprite_model`` (:mod:`raspv_spv.sprite_models`) draws the phosphenes, with
``rho_um``, ``axlambda_um`` (0: the model's default) and ``max_amplitude_xth``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from raspv_common import shipped
from raspv_common.text_files import read_yaml_file

from raspv_spv.implant_layout import EYES, LayoutError, load_layout
from raspv_spv.retinotopy import CORTICAL_MAPS
from raspv_spv.sprite_model_names import SPRITE_MODELS

DEVICES_DIR = shipped.CONFIG_DIR / "devices"
GRIDS = ("rectangular", "hexagonal")
FIELDS = ("rectangular", "circular")


class DeviceError(ValueError):
    """A device preset that does not exist or cannot be read."""


@dataclass(frozen=True)
class Device:
    """A simulated prosthesis. Angles in degrees of visual field; ``aspect`` = height / width
    of the phosphene image; ``noise_px`` in phosphene-image pixels; pulse in µA and ms."""

    name: str
    num_phosphenes: int
    fov_deg: float
    grid: str
    phosphene_fov_deg: float
    num_levels: int
    aspect: float = 1.0
    field: str = "rectangular"
    dropout: float = 0.0
    noise_px: float = 0.0
    pulse_amplitude_ua: float = 20.0
    pulse_phase_ms: float = 0.45
    description: str = ""
    layout: str = ""                   # "": the paper's lattice; else an implant layout name or YAML path
    implant_x_um: float = 0.0          # placement on the retina / cortex map [µm]
    implant_y_um: float = 0.0
    implant_rotation_deg: float = 0.0
    eye: str = "right"
    cortical_map: str = "polimeni2006"
    sprite_model: str = "gaussian"
    rho_um: float = 0.0                # 0: the sprite model's default
    axlambda_um: float = 0.0
    max_amplitude_xth: float = 3.0     # biphasic axon map: the top level's amplitude [x threshold]

    def __post_init__(self) -> None:
        problems = device_problems(self)
        if problems:
            raise DeviceError(f"device {self.name!r}: " + "; ".join(problems))

    def with_changes(self, **changes: Any) -> "Device":
        """A copy with some fields replaced (validated)."""
        return replace(self, **changes)


def device_problems(d: Device) -> list[str]:
    """What is wrong with ``d`` (empty when it is usable)."""
    out = []
    if not isinstance(d.num_phosphenes, int) or isinstance(d.num_phosphenes, bool) or d.num_phosphenes < 1:
        out.append(f"num_phosphenes must be a positive integer, got {d.num_phosphenes!r}")
    for name, lo, hi in (("fov_deg", 0.0, 170.0), ("phosphene_fov_deg", 0.0, 20.0), ("aspect", 0.0, 10.0)):
        v = getattr(d, name)
        if not _number(v) or not (lo < v < hi):
            out.append(f"{name} must be a number in ({lo}, {hi}), got {v!r}")
    if d.grid not in GRIDS:
        out.append(f"grid must be one of {', '.join(GRIDS)}, got {d.grid!r}")
    if d.field not in FIELDS:
        out.append(f"field must be one of {', '.join(FIELDS)}, got {d.field!r}")
    if not isinstance(d.num_levels, int) or isinstance(d.num_levels, bool) or not 2 <= d.num_levels <= 256:
        out.append(f"num_levels must be an integer in [2, 256], got {d.num_levels!r}")
    if not _number(d.dropout) or not 0.0 <= d.dropout <= 1.0:
        out.append(f"dropout must be in [0, 1], got {d.dropout!r}")
    if not _number(d.noise_px) or d.noise_px < 0:
        out.append(f"noise_px must be >= 0, got {d.noise_px!r}")
    if not _number(d.pulse_amplitude_ua) or d.pulse_amplitude_ua <= 0:
        out.append(f"pulse_amplitude_ua must be > 0, got {d.pulse_amplitude_ua!r}")
    if not _number(d.pulse_phase_ms) or d.pulse_phase_ms <= 0:
        out.append(f"pulse_phase_ms must be > 0, got {d.pulse_phase_ms!r}")
    if not isinstance(d.layout, str):
        out.append(f"layout must be a layout name or path, got {d.layout!r}")
    elif d.layout:
        try:
            load_layout(d.layout)
        except LayoutError as exc:
            out.append(str(exc))
    for name in ("implant_x_um", "implant_y_um", "implant_rotation_deg"):
        if not _number(getattr(d, name)):
            out.append(f"{name} must be a finite number, got {getattr(d, name)!r}")
    if d.eye not in EYES:
        out.append(f"eye must be one of {', '.join(EYES)}, got {d.eye!r}")
    if d.cortical_map not in CORTICAL_MAPS:
        out.append(f"cortical_map must be one of {', '.join(CORTICAL_MAPS)}, got {d.cortical_map!r}")
    if d.sprite_model not in SPRITE_MODELS:
        out.append(f"sprite_model must be one of {', '.join(SPRITE_MODELS)}, got {d.sprite_model!r}")
    for name in ("rho_um", "axlambda_um"):
        if not _number(getattr(d, name)) or getattr(d, name) < 0:
            out.append(f"{name} must be >= 0 (0: the sprite model's default), got {getattr(d, name)!r}")
    if not _number(d.max_amplitude_xth) or d.max_amplitude_xth < 1:
        out.append(f"max_amplitude_xth must be >= 1 (threshold), got {d.max_amplitude_xth!r}")
    return out


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


_KEYS = {f.name for f in fields(Device)}
_REQUIRED = {"name", "fov_deg", "num_levels"}
_REQUIRED_LATTICE = {"num_phosphenes", "grid", "phosphene_fov_deg"}      # unless a layout is named
_FLOAT_KEYS = ("fov_deg", "phosphene_fov_deg", "aspect", "dropout", "noise_px", "pulse_amplitude_ua", "pulse_phase_ms",
               "implant_x_um", "implant_y_um", "implant_rotation_deg", "rho_um", "axlambda_um", "max_amplitude_xth")


def preset_names() -> list[str]:
    """Names of the presets shipped in ``config/devices``."""
    return sorted(p.stem for p in DEVICES_DIR.glob("*.yaml"))


def device_from_dict(data: Any, source: str = "device") -> Device:
    """Build a :class:`Device` from a parsed YAML mapping; ``source`` names it in errors."""
    if not isinstance(data, dict):
        raise DeviceError(f"{source}: expected a mapping of device keys, got {type(data).__name__}")
    unknown = sorted(set(data) - _KEYS)
    if unknown:
        raise DeviceError(f"{source}: unknown key(s) {', '.join(unknown)}; allowed: {', '.join(sorted(_KEYS))}")
    has_layout = bool(data.get("layout"))
    missing = sorted((_REQUIRED | (set() if has_layout else _REQUIRED_LATTICE)) - set(data))
    if missing:
        raise DeviceError(f"{source}: missing key(s) {', '.join(missing)}")
    values = dict(data)
    if has_layout:
        values.setdefault("grid", "rectangular")
        values.setdefault("phosphene_fov_deg", 1.0)
        if "num_phosphenes" not in values:
            try:
                values["num_phosphenes"] = load_layout(str(values["layout"])).count
            except LayoutError as exc:
                raise DeviceError(f"{source}: {exc}") from None
    for key in _FLOAT_KEYS:
        if isinstance(values.get(key), int) and not isinstance(values.get(key), bool):
            values[key] = float(values[key])
    values["name"] = str(values["name"])
    values["description"] = str(values.get("description", ""))
    try:
        return Device(**values)
    except DeviceError as exc:
        raise DeviceError(f"{source}: {exc}") from None


def load_device(name_or_path: str | Path) -> Device:
    """A shipped preset by name (``argus_ii``) or any device YAML file by path."""
    text = str(name_or_path).strip()
    if not text:
        raise DeviceError("empty device name; presets: " + ", ".join(preset_names()))
    path = Path(text).expanduser()
    looks_like_path = path.suffix in (".yaml", ".yml") or "/" in text
    if not looks_like_path:
        path = DEVICES_DIR / f"{text}.yaml"
        if not path.is_file():
            raise DeviceError(f"unknown device preset {text!r}; presets: {', '.join(preset_names())} "
                              "(or give the path of a device YAML file)")
    elif path.is_dir():
        raise DeviceError(f"device {text!r} is a directory; give a preset name ({', '.join(preset_names())}) "
                          "or the path of a device YAML file")
    elif not path.is_file():
        raise DeviceError(f"device file {path} does not exist")
    data = read_yaml_file(path, "device YAML file", DeviceError, str(path))
    return device_from_dict(data, str(path))
