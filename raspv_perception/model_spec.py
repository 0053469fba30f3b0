"""The *model file*: a small YAML next to a user's segmentation model saying how to feed it and
what its output ids mean (no ROS). Example (``segformer.yaml`` beside ``segformer.onnx``)::

    input_size: [512, 512]          # network input width, height [px]
    scale: 255.0                    # pixels are divided by this first (1.0: the net takes 0..255)
    mean: [0.485, 0.456, 0.406]     # then (x - mean) / std, per channel
    std: [0.229, 0.224, 0.225]
    channel_order: rgb              # rgb or bgr
    layout: nchw                    # nchw or nhwc
    labels: ade20k                  # a built-in set (ade20k, coco_stuff), a list of names, or a text file
    background: false               # true: output 0 is an extra background class before the labels
    model: segformer.onnx           # optional; default: this file's name with .onnx / .pt

A label entry may carry synonyms, ``"sofa;couch"``. Every mistake raises :class:`ModelError`
with one line naming the file, the key and what is expected.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from raspv_perception.class_table import ClassTable

KEYS = ("input_size", "scale", "mean", "std", "channel_order", "layout", "labels", "background", "model")
MODEL_SUFFIXES = (".onnx", ".pt", ".pth", ".torchscript")


class ModelError(ValueError):
    """A segmentation model that cannot be used; the message is one line naming the file."""


@dataclass(frozen=True)
class ModelSpec:
    """What the model file says. ``width``/``height``: network input [px]."""

    source: Path
    model: Path
    width: int
    height: int
    scale: float
    mean: tuple[float, float, float]
    std: tuple[float, float, float]
    channel_order: str
    layout: str
    classes: ClassTable


def _numbers(value: Any, count: int, where: str, positive: bool = False) -> tuple[float, ...]:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [value] * count
    ok = (isinstance(value, (list, tuple)) and len(value) == count
          and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value))
    if not ok or (positive and any(v <= 0 for v in value)):
        raise ModelError(f"{where}: expected {count} {'positive ' if positive else ''}numbers, got {value!r}")
    return tuple(float(v) for v in value)


def _classes(value: Any, where: str, base: Path, background: bool) -> ClassTable:
    if isinstance(value, str) and value.strip():
        candidate = (base / value).expanduser()
        if candidate.suffix in (".txt", ".names", ".csv") or candidate.is_file():
            if not candidate.is_file():
                raise ModelError(f"{where}: label file {candidate} does not exist")
            try:
                entries = [ln.strip() for ln in candidate.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
            except (OSError, UnicodeDecodeError) as exc:
                raise ModelError(f"{where}: cannot read label file {candidate} ({exc})") from None
            label_set = candidate.name
        else:
            try:
                table = ClassTable.from_label_set(value)
            except KeyError as exc:
                raise ModelError(f"{where}: {exc.args[0]}, or a list of class names, or a text file") from None
            entries, label_set = [(n + (";" + ";".join(s) if s else "")) for n, s in zip(table.names, table.synonyms)], table.label_set
    elif isinstance(value, list) and value and all(isinstance(v, str) and v.strip() for v in value):
        entries, label_set = value, "custom"
    else:
        raise ModelError(f"{where}: expected a built-in label set (ade20k, coco_stuff), a list of class names "
                         f"or a text file with one name per line, got {value!r}")
    if background:
        entries = ["background"] + list(entries)
    try:
        return ClassTable.from_entries(entries, label_set)
    except ValueError as exc:
        raise ModelError(f"{where}: {exc}") from None


def load_model_spec(model: Path, spec_path: Path | None = None) -> ModelSpec:
    """Read the model file of ``model`` (``spec_path``, default ``model`` with ``.yaml``)."""
    model = Path(model)
    if spec_path is None:
        spec_path = model.with_suffix(".yaml") if model.suffix in MODEL_SUFFIXES else model
        if model.suffix in (".yaml", ".yml"):
            spec_path = model
    if model.suffix in MODEL_SUFFIXES and not model.is_file():
        raise ModelError(f"{model}: no such model file")
    if not spec_path.is_file():
        raise ModelError(f"{spec_path}: no model file; a segmentation model needs a YAML beside it giving "
                         "input_size, mean, std, channel_order and labels (see docs/perception.md#segmentation)")
    try:
        doc = yaml.safe_load(spec_path.read_text())
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark is not None else ""
        raise ModelError(f"{spec_path}: not valid YAML{at} ({getattr(exc, 'problem', exc)})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(f"{spec_path}: cannot read ({exc})") from None
    if not isinstance(doc, dict):
        raise ModelError(f"{spec_path}: expected a mapping with input_size, mean, std, labels, …")
    unknown = sorted(set(doc) - set(KEYS))
    if unknown:
        raise ModelError(f"{spec_path}: unknown key '{unknown[0]}' (allowed: {', '.join(KEYS)})")
    src = str(spec_path)
    if "model" in doc:
        if not isinstance(doc["model"], str):
            raise ModelError(f"{src}: model: expected a file name, got {doc['model']!r}")
        model = (spec_path.parent / doc["model"]).expanduser()
    if model.suffix in (".yaml", ".yml"):
        for suffix in MODEL_SUFFIXES:
            if model.with_suffix(suffix).is_file():
                model = model.with_suffix(suffix)
                break
    if not model.is_file():
        raise ModelError(f"{model}: no such model file (named by {spec_path.name})")
    if "input_size" not in doc:
        raise ModelError(f"{src}: input_size: missing; expected [width, height] of the network input in px")
    w, h = _numbers(doc["input_size"], 2, f"{src}: input_size", positive=True)
    if w != int(w) or h != int(h) or w > 8192 or h > 8192:
        raise ModelError(f"{src}: input_size: expected two whole numbers of px up to 8192, got {doc['input_size']!r}")
    scale = _numbers(doc.get("scale", 255.0), 1, f"{src}: scale", positive=True)[0]
    mean = _numbers(doc.get("mean", [0.0, 0.0, 0.0]), 3, f"{src}: mean")
    std = _numbers(doc.get("std", [1.0, 1.0, 1.0]), 3, f"{src}: std", positive=True)
    order = doc.get("channel_order", "rgb")
    if order not in ("rgb", "bgr"):
        raise ModelError(f"{src}: channel_order: expected rgb or bgr, got {order!r}")
    layout = doc.get("layout", "nchw")
    if layout not in ("nchw", "nhwc"):
        raise ModelError(f"{src}: layout: expected nchw or nhwc, got {layout!r}")
    background = doc.get("background", False)
    if not isinstance(background, bool):
        raise ModelError(f"{src}: background: expected true or false, got {background!r}")
    if "labels" not in doc:
        raise ModelError(f"{src}: labels: missing; expected ade20k, coco_stuff, a list of names or a text file")
    classes = _classes(doc["labels"], f"{src}: labels", spec_path.parent, background)
    return ModelSpec(spec_path, model, int(w), int(h), scale, mean, std, order, layout, classes)
