"""A training configuration: the data recipe, the device, the networks and the schedule (YAML).

One file says everything a trained encoder depends on, so the shipped weights sit next to the
file that produced them::

    name: optimist
    data: {train_worlds: [apartment, stairs], test_worlds: [office], ...}   # DataRecipe
    device: optimist            # a preset name or device YAML, as the spv node's `device`
    spv: {width: 128}           # any other spv_config setting of the twin (width, num_phosphenes, ...)
    target: {range_m: 3.0, stride_px: 4}
    encoder: {focal_px: 64.0, channels: [grey, nearness, ...], features: 16}
    decoder: {features: 16}
    train: {epochs: 10, batch_size: 32, lr: 0.002, encoder_lr: 0.001, charge_weight: 0.05, seed: 0, threads: 1}
    observer: {epochs: 20}

Unknown keys are errors (one line naming the file and the key).
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Mapping

from raspv_learn.dataset import DataError, DataRecipe
from raspv_spv.modes.learned import CHANNELS


class ConfigError(ValueError):
    """A training configuration that cannot be used (one line)."""


@dataclass(frozen=True)
class TargetSpec:
    """What the decoder must recover: the walker class (floor, wall, obstacle) of each cell of
    ``stride_px`` × ``stride_px`` phosphene-image pixels, seen within ``range_m`` metres
    (depth along the optical axis; the depth modes' default ``max_depth``); farther, no
    reading or outside the camera: not scored."""

    range_m: float = 3.0
    stride_px: int = 4


@dataclass(frozen=True)
class EncoderSpec:
    """``focal_px``: the input grid's focal length (its angular resolution; 64 px ≈ 0.9° per
    cell at the centre); ``features``: width of the first layer."""

    focal_px: float = 64.0
    channels: tuple[str, ...] = CHANNELS
    features: int = 16


@dataclass(frozen=True)
class DecoderSpec:
    features: int = 16


@dataclass(frozen=True)
class TrainSpec:
    """``lr``: the decoder's learning rate, ``encoder_lr`` the encoder's (Adam, cosine decay);
    ``code_weight``: weight of the starting curriculum — the stimulation pulled towards the
    walker-class code of each phosphene's ray (floor off, walls half, obstacles full) —
    annealed linearly to 0 over the first ``code_warmup`` of the steps;
    ``charge_weight``: λ of the charge penalty λ·mean(level/(N_L−1)) (the charge a frame
    delivers is proportional to the summed levels), ramped up from 0 over the first
    ``charge_warmup`` of the steps (a penalty at full weight from the start switches every
    phosphene off before the decoder has learnt to read any); ``val_fraction``: training-world
    frames kept out to pick the best epoch (never the test worlds)."""

    epochs: int = 10
    batch_size: int = 32
    lr: float = 0.002
    encoder_lr: float = 0.001
    weight_decay: float = 1e-4
    code_weight: float = 1.0
    code_warmup: float = 0.3
    charge_weight: float = 0.05
    charge_warmup: float = 0.3
    val_fraction: float = 0.1
    seed: int = 0
    threads: int = 1


@dataclass(frozen=True)
class ObserverSpec:
    """The computational observer: the decoder architecture trained alone on each mode's
    phosphene images (same epochs, batch and learning rate for every mode)."""

    epochs: int = 20
    batch_size: int = 32
    lr: float = 0.002


@dataclass(frozen=True)
class LearnConfig:
    name: str
    device: str
    data: DataRecipe = field(default_factory=DataRecipe)
    spv: Mapping[str, Any] = field(default_factory=lambda: {"width": 128})
    target: TargetSpec = field(default_factory=TargetSpec)
    encoder: EncoderSpec = field(default_factory=EncoderSpec)
    decoder: DecoderSpec = field(default_factory=DecoderSpec)
    train: TrainSpec = field(default_factory=TrainSpec)
    observer: ObserverSpec = field(default_factory=ObserverSpec)
    source: str = ""

    def spv_config(self, mode: str = "grey", **extra):
        """The :class:`~raspv_spv.config.SpvConfig` of the twin (temporal model off: training
        sees each frame's steady state, what a level held for 10 frames shows)."""
        from raspv_spv.config import spv_config

        settings = {"temporal": False, **dict(self.spv), **extra}
        return spv_config(self.device, mode=mode, **settings)

    def _values(self) -> dict:
        return {**asdict(self), "data": self.data.values()}

    def key(self) -> str:
        """Hash of everything the trained weights depend on (not the observer's schedule)."""
        values = {k: v for k, v in self._values().items() if k not in ("source", "observer", "name")}
        return hashlib.sha256(json.dumps(values, sort_keys=True, default=list).encode()).hexdigest()[:16]

    def observer_key(self) -> str:
        """Hash of everything a hand-designed mode's observer score depends on: the data, the
        device and twin, the targets, the decoder and its schedule, the seed and the validation
        split — not how the encoder is trained (a retrained encoder keeps the modes' rows)."""
        t = self.train
        values = {k: v for k, v in self._values().items() if k in ("data", "device", "spv", "target", "decoder",
                                                                  "observer")}
        values["train"] = {"seed": t.seed, "val_fraction": t.val_fraction, "threads": t.threads}
        return hashlib.sha256(json.dumps(values, sort_keys=True, default=list).encode()).hexdigest()[:16]

    def as_dict(self) -> dict:
        out = self._values()
        out.pop("source")
        return json.loads(json.dumps(out, default=list))


_SECTIONS = {"target": TargetSpec, "encoder": EncoderSpec, "decoder": DecoderSpec, "train": TrainSpec,
             "observer": ObserverSpec}


def _section(cls, values: Any, where: str):
    if values is None:
        return cls()
    if not isinstance(values, Mapping):
        raise ConfigError(f"{where}: must be a mapping, got {type(values).__name__}")
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(unknown)} (allowed: {', '.join(known)})")
    out = cls()
    for k, v in values.items():
        default = getattr(out, k)
        if isinstance(default, tuple):
            if not isinstance(v, (list, tuple)):
                raise ConfigError(f"{where}.{k}: must be a list, got {v!r}")
            v = tuple(v)
        elif isinstance(default, bool) or not isinstance(v, (int, float)) or isinstance(v, bool):
            if type(v) is not type(default):
                raise ConfigError(f"{where}.{k}: must be a {type(default).__name__}, got {v!r}")
        elif isinstance(default, int) and not isinstance(v, int):
            raise ConfigError(f"{where}.{k}: must be an integer, got {v!r}")
        out = replace(out, **{k: type(default)(v) if not isinstance(default, tuple) else v})
    return out


def config_from_mapping(values: Mapping[str, Any], source: str = "config") -> LearnConfig:
    if not isinstance(values, Mapping):
        raise ConfigError(f"{source}: must be a YAML mapping")
    allowed = {"name", "device", "data", "spv", *_SECTIONS}
    unknown = sorted(set(values) - allowed)
    if unknown:
        raise ConfigError(f"{source}: unknown key(s) {', '.join(unknown)} (allowed: {', '.join(sorted(allowed))})")
    for key in ("name", "device"):
        if not isinstance(values.get(key), str) or not values[key]:
            raise ConfigError(f"{source}: '{key}' must be a non-empty string")
    try:
        data = DataRecipe.from_mapping(values.get("data") or {}, f"{source}: data")
    except DataError as exc:
        raise ConfigError(str(exc)) from None
    spv = values.get("spv") or {}
    if not isinstance(spv, Mapping):
        raise ConfigError(f"{source}: spv: must be a mapping of spv_config settings")
    sections = {k: _section(cls, values.get(k), f"{source}: {k}") for k, cls in _SECTIONS.items()}
    config = LearnConfig(values["name"], values["device"], data, dict(spv), source=source, **sections)
    _check(config)
    return config


def _check(c: LearnConfig) -> None:
    where = c.source
    bad = [ch for ch in c.encoder.channels if ch not in CHANNELS]
    if bad or not c.encoder.channels:
        raise ConfigError(f"{where}: encoder.channels: unknown {bad} (known: {', '.join(CHANNELS)})")
    problems = []
    if c.target.range_m <= 0 or c.target.stride_px < 1:
        problems.append("target.range_m must be > 0 and target.stride_px >= 1")
    if c.encoder.focal_px <= 0 or c.encoder.features < 4 or c.decoder.features < 4:
        problems.append("encoder.focal_px must be > 0 and the features >= 4")
    t = c.train
    if (t.epochs < 1 or t.batch_size < 1 or t.lr <= 0 or t.encoder_lr <= 0 or t.charge_weight < 0
            or not 0 <= t.charge_warmup <= 1 or t.code_weight < 0 or not 0 < t.code_warmup <= 1
            or not 0 < t.val_fraction < 0.5):
        problems.append("train: epochs and batch_size >= 1, lr and encoder_lr > 0, charge_weight and code_weight "
                        ">= 0, charge_warmup in [0, 1], code_warmup in (0, 1], val_fraction in (0, 0.5)")
    if c.observer.epochs < 1 or c.observer.batch_size < 1 or c.observer.lr <= 0:
        problems.append("observer: epochs and batch_size >= 1, lr > 0")
    if problems:
        raise ConfigError(f"{where}: " + "; ".join(problems))
    try:
        c.spv_config()
    except (ValueError, KeyError, OSError) as exc:
        raise ConfigError(f"{where}: device/spv: {exc}") from None


def load_config(path: str | Path) -> LearnConfig:
    """The configuration in ``path`` (or a shipped one by name: ``raspv_learn/configs/NAME.yaml``)."""
    import yaml

    p = Path(path)
    if not p.exists() and not p.suffix:
        p = Path(__file__).resolve().parent / "configs" / f"{path}.yaml"
    try:
        values = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise ConfigError(f"{path}: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: invalid YAML ({str(exc).splitlines()[0]})") from None
    return config_from_mapping(values, str(p))
