"""Device presets: the parameters of a simulated prosthesis, from YAML (no ROS).

Presets ship in ``config/devices/<name>.yaml`` (default, argus_ii, argus_iii, alpha_ims,
optimist); any YAML file with the same keys is a device too. Unknown keys, missing keys and
impossible values are reported with the file name and what is allowed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from raspv_common.text_files import read_yaml_file

DEVICES_DIR = Path(__file__).resolve().parent.parent / "config" / "devices"
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
    return out


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


_KEYS = {f.name for f in fields(Device)}
_REQUIRED = {"name", "num_phosphenes", "fov_deg", "grid", "phosphene_fov_deg", "num_levels"}


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
    missing = sorted(_REQUIRED - set(data))
    if missing:
        raise DeviceError(f"{source}: missing key(s) {', '.join(missing)}")
    values = dict(data)
    for key in ("fov_deg", "phosphene_fov_deg", "aspect", "dropout", "noise_px", "pulse_amplitude_ua", "pulse_phase_ms"):
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
