"""Configuration of the phosphene simulator: a device preset plus explicit choices (no ROS).

:func:`spv_config` is the one place that turns user values (the spv node's parameters, or
keyword arguments of the offline API) into a :class:`SpvConfig`: the ``device`` preset gives
the prosthesis values, and any explicitly given value overrides it. For the node, 0 (numbers)
and "" (names) mean "the device's value", so ``raspv param set spv device argus_ii`` switches
every value that was not set explicitly.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from raspv_spv.device import Device, load_device
from raspv_spv.implant_layout import LayoutSpec
from raspv_spv.phosphene_map import MapSpec
from raspv_spv.sprite_models import SpriteSpec
from raspv_spv.temporal_lut import TemporalLUTConfig
from raspv_spv.temporal_recursive import DEFAULT_RECOVERY_MS, RecursiveConfig

TEMPORAL_UPDATES = ("recursive", "lut")

# Device fields a user may override (the value 0 / "" means: keep the device's).
DEVICE_OVERRIDES = ("num_phosphenes", "fov_deg", "grid", "field", "phosphene_fov_deg", "num_levels",
                    "pulse_amplitude_ua", "pulse_phase_ms", "layout", "sprite_model", "rho_um", "axlambda_um")
# Device fields whose own default (0) is meaningful, so an explicit 0 must be honoured.
DEVICE_DEFECTS = ("dropout", "noise_px")


@dataclass(frozen=True)
class SpvConfig:
    """Everything a :class:`~raspv_spv.simulator.PhospheneSimulator` is built from.

    ``device``: the resolved prosthesis (after overrides). ``width`` × ``height``: phosphene
    image px. ``frame_rate``: display rate [Hz] (the look-up table's frame rate).
    ``temporal_update``: ``lut`` (the paper's 10-frame look-up table, one pulse per display frame)
    or ``recursive`` (:mod:`raspv_spv.temporal_recursive`: pulses at ``pulse_rate`` Hz, brightness
    at any display time; ``recovery_ms`` its charge recovery, ``inf`` pulse2percept's model).
    ``mode_settings``: values modes read (``max_depth`` m, ``edge_low``/``edge_high``, …).
    """

    device: Device
    width: int = 800
    height: int = 800
    seed: int = 0
    mode: str = "grey"
    overlays: tuple[str, ...] = ()
    temporal: bool = True
    temporal_model: str = "horsager2009"
    temporal_sample: str = "mean"
    temporal_update: str = "lut"
    pulse_rate: float = 50.0
    recovery_ms: float = DEFAULT_RECOVERY_MS
    frame_rate: float = 50.0
    output_format: str = "mono8"
    mode_settings: Mapping[str, Any] = field(default_factory=dict)

    def map_spec(self) -> MapSpec:
        d = self.device
        layout = (LayoutSpec(d.layout, d.implant_x_um, d.implant_y_um, d.implant_rotation_deg, d.cortical_map)
                  if d.layout else None)
        return MapSpec(self.width, self.height, d.num_phosphenes, d.grid, d.field, d.fov_deg,
                       d.phosphene_fov_deg, d.dropout, d.noise_px, self.seed, layout)

    def sprite_spec(self) -> SpriteSpec:
        """The sprite model and its parameters; pulses at the display rate (one per frame), or at
        the recursive temporal model's pulse rate."""
        d = self.device
        rate = self.pulse_rate if self.temporal and self.temporal_update == "recursive" else self.frame_rate
        return SpriteSpec(d.sprite_model, d.rho_um, d.axlambda_um, d.eye, d.num_levels, d.max_amplitude_xth,
                          d.pulse_phase_ms, rate, d.pulse_amplitude_ua)

    def __post_init__(self) -> None:
        if self.temporal_update not in TEMPORAL_UPDATES:
            raise ValueError(f"temporal_update must be one of {', '.join(TEMPORAL_UPDATES)}, got {self.temporal_update!r}")

    def recursive_config(self) -> RecursiveConfig:
        d = self.device
        return RecursiveConfig(model=self.temporal_model, pulse_rate_hz=self.pulse_rate,
                               pulse_amplitude_ua=d.pulse_amplitude_ua, pulse_phase_ms=d.pulse_phase_ms,
                               recovery_ms=self.recovery_ms)

    def lut_config(self) -> TemporalLUTConfig:
        d = self.device
        return TemporalLUTConfig(model=self.temporal_model, frame_ms=1000.0 / self.frame_rate,
                                 pulse_amplitude_ua=d.pulse_amplitude_ua, pulse_phase_ms=d.pulse_phase_ms,
                                 sample=self.temporal_sample)


def spv_config(device: str | Device = "default", *, width: int = 800, height: int = 0, seed: int = 0,
               mode: str = "grey", overlays: tuple[str, ...] | list[str] = (), temporal: bool = True,
               temporal_model: str = "horsager2009", temporal_sample: str = "mean", temporal_update: str = "lut",
               pulse_rate: float = 50.0, recovery_ms: float = DEFAULT_RECOVERY_MS, frame_rate: float = 50.0,
               output_format: str = "mono8", mode_settings: Mapping[str, Any] | None = None,
               dropout: float | None = None, noise_px: float | None = None, **device_overrides: Any) -> SpvConfig:
    """A :class:`SpvConfig` from a device preset (name, YAML path or :class:`Device`) and
    overrides. ``height`` 0 means ``width`` × the device's aspect ratio; device overrides with
    value 0, "" or None are ignored (they mean "the device's value")."""
    dev = device if isinstance(device, Device) else load_device(device)
    unknown = sorted(set(device_overrides) - set(DEVICE_OVERRIDES))
    if unknown:
        raise ValueError(f"unknown setting(s) {', '.join(unknown)}; device settings: {', '.join(DEVICE_OVERRIDES + DEVICE_DEFECTS)}")
    changes = {k: v for k, v in device_overrides.items() if v not in (0, 0.0, "", None)}
    if dropout is not None:
        changes["dropout"] = float(dropout)
    if noise_px is not None:
        changes["noise_px"] = float(noise_px)
    dev = dev.with_changes(**changes) if changes else dev
    if height == 0:
        height = max(16, int(round(width * dev.aspect)))
    return SpvConfig(dev, int(width), int(height), int(seed), mode, tuple(overlays), bool(temporal), temporal_model,
                     temporal_sample, temporal_update, float(pulse_rate), float(recovery_ms), float(frame_rate),
                     output_format, dict(mode_settings or {}))



def config_from_node_params(p: Mapping[str, Any]) -> SpvConfig:
    """The :class:`SpvConfig` of the spv node's parameter values (see ``spv_params.py``):
    0, "" and −1 (dropout, noise) mean the device's value; every parameter is also handed to
    the modes as their settings."""
    return spv_config(
        p["device"], width=p["width"], height=p["height"], seed=p["seed"], mode=p["mode"], overlays=p["overlays"],
        temporal=p["temporal"], temporal_model=p["temporal_model"], temporal_sample=p["temporal_sample"],
        temporal_update=p["temporal_update"], pulse_rate=p["pulse_rate"],
        recovery_ms=p["charge_recovery_ms"] if p["charge_recovery_ms"] > 0 else float("inf"), frame_rate=p["rate"], output_format=p["output_format"], mode_settings=dict(p),
        dropout=None if p["dropout"] < 0 else p["dropout"], noise_px=None if p["noise_px"] < 0 else p["noise_px"],
        **{k: p[k] for k in DEVICE_OVERRIDES})
