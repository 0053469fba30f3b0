"""The authors' viewer keys → changes of the ``spv`` node's parameters (no I/O, no rclpy).

=========  ==============================================  =========================
key        change                                          spv parameter
=========  ==============================================  =========================
``+ -``    number of phosphenes × 1.1 / × 0.9              ``num_phosphenes``
``* /``    phosphene size × 1.1 / × 0.9                    ``phosphene_fov_deg``
``v V``    field of view − / + 1°                          ``fov_deg``
``n N``    position noise − / + 1 px                       ``noise_px``
``o O``    dropout − / + 0.05                              ``dropout``
``l L``    luminance levels − / + 1                        ``num_levels``
``j J``    chess tile − / + 0.25 m in a chess mode,        ``chess_tile`` /
           otherwise max depth − / + 0.5 m                 ``max_depth``
``.``      grid rectangular ↔ hexagonal                    ``grid``
``,``      field rectangular ↔ circular                    ``field``
``1``–``9``  the n-th representation mode of ``modes``     ``mode``
``t T``    highlight the next / previous class of          ``highlight.classes``
           ``HIGHLIGHT_CLASSES``
``y``      highlight overlay on / off                      ``overlays``
=========  ==============================================  =========================

The bridge reads the current values it needs, computes the new one here, and sets it; the spv
node validates it (and refuses with a reason out of range). The spv node's device parameters
use 0 / "" / −1 for "the device preset's value" (raspv_spv/spv_params.py); a key then starts
from the preset's value, which the caller passes as ``device``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence


@dataclass(frozen=True)
class KeyChange:
    name: str           # spv parameter
    value: Any
    text: str           # what the subject is told, e.g. "num_phosphenes 1000 → 1100"


def _scale(factor: float, lo: float, as_int: bool = False) -> Callable[[Any], Any]:
    def apply(v: Any) -> Any:
        if as_int:
            new = int(round(v * factor))
            if new == v:                               # small counts must still move
                new = v + (1 if factor > 1 else -1)
            return max(int(lo), new)
        return max(lo, round(float(v) * factor, 4))
    return apply


def _step(delta: float, lo: float, hi: float = float("inf"), as_int: bool = False) -> Callable[[Any], Any]:
    def apply(v: Any) -> Any:
        new = min(hi, max(lo, v + delta))
        return int(new) if as_int else round(float(new), 4)
    return apply


def _toggle(a: str, b: str) -> Callable[[Any], Any]:
    return lambda v: b if v == a else a


# key → (parameter, function of its current value)
SIMPLE_KEYS: dict[str, tuple[str, Callable[[Any], Any]]] = {
    "+": ("num_phosphenes", _scale(1.1, 1, as_int=True)),
    "-": ("num_phosphenes", _scale(0.9, 1, as_int=True)),
    "*": ("phosphene_fov_deg", _scale(1.1, 0.01)),
    "/": ("phosphene_fov_deg", _scale(0.9, 0.01)),
    "v": ("fov_deg", _step(-1.0, 1.0)),
    "V": ("fov_deg", _step(+1.0, 1.0)),
    "n": ("noise_px", _step(-1.0, 0.0)),
    "N": ("noise_px", _step(+1.0, 0.0)),
    "o": ("dropout", _step(-0.05, 0.0, 1.0)),
    "O": ("dropout", _step(+0.05, 0.0, 1.0)),
    "l": ("num_levels", _step(-1, 2, as_int=True)),
    "L": ("num_levels", _step(+1, 2, as_int=True)),
    ".": ("grid", _toggle("rectangular", "hexagonal")),
    ",": ("field", _toggle("rectangular", "circular")),
}
# spv parameters whose sentinel value means "the device preset's value"
DEVICE_SENTINELS: dict[str, Any] = {"num_phosphenes": 0, "fov_deg": 0.0, "phosphene_fov_deg": 0.0,
                                    "num_levels": 0, "grid": "", "field": "", "dropout": -1.0, "noise_px": -1.0}
DEPTH_KEYS = {"j": -1, "J": +1}          # chess tile ±0.25 m or max depth ±0.5 m
MODE_KEYS = frozenset("123456789")      # one character each: "" or "12" is no mode key
# What t / T cycle through: the things a subject is asked to find in the shipped worlds (ADE20K
# names or synonyms, so they also work with an ADE20K or COCO-Stuff model).
HIGHLIGHT_CLASSES = ("person", "laptop", "bin", "door", "chair", "table")
HIGHLIGHT_KEYS = {"t": +1, "T": -1}
OVERLAY_TOGGLE_KEY = "y"


def is_chess_mode(mode: Any) -> bool:
    return isinstance(mode, str) and "chess" in mode.lower()


def uses_device_value(name: str, value: Any) -> bool:
    """True when spv parameter ``name`` holds its "the device's value" sentinel."""
    if name not in DEVICE_SENTINELS:
        return False
    if name in ("dropout", "noise_px"):
        return isinstance(value, (int, float)) and value < 0
    return value == DEVICE_SENTINELS[name]


def parameters_needed(key: str) -> list[str]:
    """The spv parameters whose current values ``key`` depends on ([] for mode keys; "device"
    for keys on device values); KeyError for keys that do nothing."""
    if key in SIMPLE_KEYS:
        name = SIMPLE_KEYS[key][0]
        return [name, "device"] if name in DEVICE_SENTINELS else [name]
    if key in DEPTH_KEYS:
        return ["mode", "chess_tile", "max_depth"]
    if key in MODE_KEYS:
        return []
    if key in HIGHLIGHT_KEYS:
        return ["highlight.classes"]
    if key == OVERLAY_TOGGLE_KEY:
        return ["overlays"]
    raise KeyError(key)


def key_change(key: str, current: Mapping[str, Any], modes: Sequence[str],
               device: Mapping[str, Any] | None = None) -> KeyChange:
    """The parameter change a key asks for, given the current spv values (``parameters_needed``;
    None for parameters the spv node does not have) and the device preset's values.

    KeyError for keys that do nothing; ValueError when the key cannot apply (a mode number
    beyond ``modes``, a parameter the spv node lacks)."""
    def value(name: str) -> Any:
        v = current.get(name)
        if v is None:
            raise ValueError(f"the spv node has no parameter {name!r}")
        if uses_device_value(name, v):
            if device is None or name not in device:
                raise ValueError(f"{name} is the device's value, and the device is unknown")
            return device[name]
        return v

    if key in SIMPLE_KEYS:
        name, fn = SIMPLE_KEYS[key]
        old = value(name)
        new = fn(old)
        return KeyChange(name, new, f"{name} {old} → {new}")
    if key in DEPTH_KEYS:
        sign = DEPTH_KEYS[key]
        if is_chess_mode(current.get("mode")):
            old = value("chess_tile")
            name, new = "chess_tile", round(max(0.05, old + sign * 0.25), 4)
        else:
            old = value("max_depth")
            name, new = "max_depth", round(max(0.5, old + sign * 0.5), 4)
        return KeyChange(name, new, f"{name} {old} → {new}")
    if key in MODE_KEYS:
        i = int(key) - 1
        if i >= len(modes):
            raise ValueError(f"key {key}: only {len(modes)} modes ({', '.join(modes)})")
        return KeyChange("mode", modes[i], f"mode {modes[i]}")
    if key in HIGHLIGHT_KEYS:
        old = list(value("highlight.classes"))
        cycle = HIGHLIGHT_CLASSES
        i = cycle.index(old[0]) + HIGHLIGHT_KEYS[key] if old and old[0] in cycle else 0
        new = [cycle[i % len(cycle)]]
        return KeyChange("highlight.classes", new, f"highlight {new[0]}")
    if key == OVERLAY_TOGGLE_KEY:
        old = list(value("overlays"))
        new = [o for o in old if o != "highlight"] if "highlight" in old else old + ["highlight"]
        return KeyChange("overlays", new, f"highlight {'on' if 'highlight' in new else 'off'}")
    raise KeyError(key)
