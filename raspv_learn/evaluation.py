"""A pre-registered evaluation of the learned encoders (``raspv_learn/evaluations/NAME.yaml``).

The file fixes, before any encoder is trained for it, what is scored (test worlds, frames,
frame seed), who (configurations, training seeds), under which depth (realistic sensor model
and perfect), how (modes, metric, bootstrap) and the target. Its SHA-256 is recorded in every
model trained for it and in every ledger entry of a scoring (:mod:`raspv_learn.ledger`).
:func:`configuration_for` turns a shipped configuration into the one trained and scored for
the evaluation: the evaluation's test worlds, frames and frame seed in the data recipe, the
depth condition's sensor model, the training seed.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Mapping

from raspv_learn.config import ConfigError, LearnConfig

EVALUATIONS_DIR = Path(__file__).resolve().parent / "evaluations"
_KEYS = {"name", "test_worlds", "test_frames_per_world", "frame_seed", "configurations", "training_seeds",
         "shipped_seed", "depth", "primary_depth", "modes", "metric", "bootstrap", "target"}


class EvaluationError(ValueError):
    """An evaluation file that cannot be used (one line)."""


@dataclass(frozen=True)
class Evaluation:
    name: str
    path: Path
    sha256: str                                     # of the file's bytes: what models and ledger record
    test_worlds: tuple[str, ...]
    test_frames_per_world: int
    frame_seed: int
    configurations: tuple[str, ...]
    training_seeds: tuple[int, ...]
    shipped_seed: int
    depth: Mapping[str, Mapping[str, float] | None]  # condition → depth-sensor settings (None: perfect)
    primary_depth: str
    modes: tuple[str, ...]
    metric: str
    resamples: int
    confidence: float
    bootstrap_seed: int
    target_points: float
    target_bound: str

    def record(self) -> dict:
        """What a model trained for this evaluation records."""
        return {"name": self.name, "sha256": self.sha256, "file": f"raspv_learn/evaluations/{self.path.name}"}


def load_evaluation(name_or_path: str | Path) -> Evaluation:
    """The evaluation in a YAML file, or a shipped one by name."""
    import yaml

    p = Path(name_or_path)
    if not p.exists() and not p.suffix:
        p = EVALUATIONS_DIR / f"{name_or_path}.yaml"
    try:
        raw = p.read_bytes()
        v = yaml.safe_load(raw)
    except OSError as exc:
        raise EvaluationError(f"evaluation {name_or_path}: {exc.strerror} ({p})") from None
    except yaml.YAMLError as exc:
        raise EvaluationError(f"{p}: invalid YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(v, Mapping) or set(v) != _KEYS:
        got = set(v) if isinstance(v, Mapping) else set()
        raise EvaluationError(f"{p}: an evaluation needs exactly the keys {', '.join(sorted(_KEYS))} "
                              f"(missing {sorted(_KEYS - got)}, unknown {sorted(got - _KEYS)})")
    try:
        depth = {str(k): (None if s is None else {str(a): float(b) for a, b in dict(s).items()})
                 for k, s in dict(v["depth"]).items()}
        ev = Evaluation(str(v["name"]), p, hashlib.sha256(raw).hexdigest(), tuple(map(str, v["test_worlds"])),
                        int(v["test_frames_per_world"]), int(v["frame_seed"]), tuple(map(str, v["configurations"])),
                        tuple(int(s) for s in v["training_seeds"]), int(v["shipped_seed"]), depth,
                        str(v["primary_depth"]), tuple(map(str, v["modes"])), str(v["metric"]),
                        int(v["bootstrap"]["resamples"]), float(v["bootstrap"]["confidence"]),
                        int(v["bootstrap"]["seed"]), float(v["target"]["points"]), str(v["target"]["bound"]))
    except (TypeError, ValueError, KeyError) as exc:
        raise EvaluationError(f"{p}: malformed ({type(exc).__name__}: {exc})") from None
    problems = []
    if ev.primary_depth not in ev.depth:
        problems.append(f"primary_depth {ev.primary_depth!r} is not one of depth's conditions {sorted(ev.depth)}")
    if ev.metric not in ("iou_obstacle", "iou_floor", "iou_wall"):
        problems.append(f"metric must be a class IoU (iou_obstacle, iou_floor, iou_wall), got {ev.metric!r}")
    if not ev.training_seeds or ev.shipped_seed not in ev.training_seeds:
        problems.append("training_seeds must be non-empty and hold shipped_seed")
    if ev.target_bound != "lower" or not 0 < ev.confidence < 1 or ev.resamples < 100:
        problems.append("target.bound must be 'lower', bootstrap.confidence in (0, 1), resamples >= 100")
    if problems:
        raise EvaluationError(f"{p}: " + "; ".join(problems))
    return ev


def depth_sensor_of(evaluation: Evaluation, condition: str):
    """The :class:`~raspv_sim.depth_sensor.DepthSensorConfig` of a depth condition (None: perfect)."""
    from raspv_sim.depth_sensor import DepthSensorConfig

    if condition not in evaluation.depth:
        raise EvaluationError(f"{evaluation.name}: no depth condition {condition!r} (has {sorted(evaluation.depth)})")
    s = evaluation.depth[condition]
    if s is None:
        return None
    try:
        return DepthSensorConfig(**{k: (int(x) if k in ("edge_width", "dark_level") else x) for k, x in s.items()})
    except (TypeError, ValueError) as exc:
        raise EvaluationError(f"{evaluation.path}: depth.{condition}: {exc}") from None


def configuration_for(config: LearnConfig, evaluation: Evaluation, seed: int, condition: str | None = None
                      ) -> LearnConfig:
    """``config`` as trained and scored for ``evaluation`` with training ``seed`` under the depth
    ``condition`` (default: the primary one): the evaluation's test worlds, frames and frame
    seed, that depth sensor, that seed for the encoder, the validation split and the observer."""
    if config.name not in evaluation.configurations:
        raise ConfigError(f"{config.name}: not a configuration of evaluation {evaluation.name} "
                          f"({', '.join(evaluation.configurations)})")
    if seed not in evaluation.training_seeds:
        raise ConfigError(f"seed {seed}: not a training seed of evaluation {evaluation.name} "
                          f"({', '.join(map(str, evaluation.training_seeds))})")
    sensor = depth_sensor_of(evaluation, condition or evaluation.primary_depth)
    sensor_values: Any = None if sensor is None else {k: getattr(sensor, k) for k in sensor.__dataclass_fields__}
    data = replace(config.data, test_worlds=evaluation.test_worlds,
                   test_frames_per_world=evaluation.test_frames_per_world, seed=evaluation.frame_seed,
                   depth_sensor=sensor_values)
    data.check(f"{config.name} for {evaluation.name}")
    return replace(config, data=data, train=replace(config.train, seed=seed))


def run_folder(evaluation: Evaluation, config_name: str, seed: int, root: str | Path = "runs/learn") -> Path:
    """Where the model of (configuration, seed) trained for ``evaluation`` lives."""
    return Path(root) / evaluation.name / f"{config_name}-seed{seed}"
