"""``learned``: a virtual patient whose steering is a small network trained on phosphene images
by imitating an expert in the simulator (no rclpy, no torch: onnxruntime runs it).

It perceives what every policy perceives — the displayed brightness of each phosphene and
where it is (``/spv/map``) — and knows what ``navigate`` knows: where the goal is from its start
and how it moved since (path integration of its own commands, drifting), and when it bumps into
something (touch: it steps back and turns, as ``navigate`` does). Each frame:

1. the phosphenes are drawn into a ``G × G`` image (:func:`phosphene_image`: each phosphene's
   brightness at its place in the phosphene image, the brighter where two share a cell), so the
   network does not depend on the layout's order;
2. the goal it was told about, relative to its path-integrated pose: (cos, sin) of its bearing
   and its distance / ``GOAL_SCALE_M`` (capped at 1) — :func:`goal_features`;
3. the network (``image`` (1, 1, G, G), ``goal`` (1, 3) → ``command`` (1, 2) in −1..1) gives
   the walking speed and turning rate as fractions of the subject's ``max_linear`` and
   ``max_angular`` — so a subject's ability (speed, reaction time, threshold, noise) acts on
   the learned policy as on the scripted ones.

The model file is an ONNX file with metadata ``raspv_patient`` (JSON: grid size, the spv
parameters and tasks it was trained on, the data size); the shipped one is
``raspv_experiments/models/learned_patient.onnx`` (``models/learned_patient.md``: how it was
trained). Training: :mod:`raspv_experiments.demonstrations` (the expert's frames, from the
cores in one process) and :mod:`raspv_learn.patient` (torch, the ``learn`` extra).
"""
from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np

from raspv_experiments.navigate_policy import Navigate, _wrap
from raspv_experiments.policies import PhospheneLayout, PolicyConfig

MODELS = Path(__file__).resolve().parent / "models"
DEFAULT_MODEL = MODELS / "learned_patient.onnx"
GRID = 32                     # phosphene image size (cells per side)
GOAL_SCALE_M = 5.0            # goal distance feature: metres / this, capped at 1


class LearnedModelError(ValueError):
    """A model file that is missing or not a learned virtual patient."""


def phosphene_image(layout: PhospheneLayout, brightness: np.ndarray, grid: int = GRID) -> np.ndarray:
    """(grid, grid) float32: each phosphene's brightness in the cell of its place in the
    phosphene image (x right, y down), the brightest where several share a cell."""
    img = np.zeros(grid * grid, np.float32)
    np.maximum.at(img, _cells(layout, grid), np.asarray(brightness, np.float32))
    return img.reshape(grid, grid)


def _cells(layout: PhospheneLayout, grid: int) -> np.ndarray:
    col = np.clip((layout.x / max(layout.width, 1) * grid).astype(int), 0, grid - 1)
    row = np.clip((layout.y / max(layout.height, 1) * grid).astype(int), 0, grid - 1)
    return row * grid + col


def goal_features(pose: np.ndarray, goal: np.ndarray | None) -> np.ndarray:
    """(3,) float32: cos and sin of the goal's bearing from the body and its distance /
    GOAL_SCALE_M (≤ 1); pose (x, y, heading) and goal (x, y) in the start frame [m, rad]."""
    if goal is None:
        return np.array([1.0, 0.0, 1.0], np.float32)
    dx, dy = goal[0] - pose[0], goal[1] - pose[1]
    b = float(_wrap(math.atan2(dy, dx) - pose[2]))
    return np.array([math.cos(b), math.sin(b), min(math.hypot(dx, dy) / GOAL_SCALE_M, 1.0)], np.float32)


@functools.lru_cache(maxsize=4)
def load_model(path: str):
    """(onnxruntime session, metadata dict) of a learned-patient model file, cached."""
    import onnxruntime as ort

    p = Path(path)
    if not p.is_file():
        raise LearnedModelError(f"learned virtual patient: no model file {p} (train one: raspv learn patient train)")
    try:
        session = ort.InferenceSession(str(p), providers=["CPUExecutionProvider"])
    except Exception as exc:                      # onnxruntime raises its own types for a bad file
        raise LearnedModelError(f"learned virtual patient: {p} is not an ONNX model ({exc})") from None
    meta = session.get_modelmeta().custom_metadata_map
    if "raspv_patient" not in meta:
        raise LearnedModelError(f"learned virtual patient: {p} has no raspv_patient metadata (not a patient model)")
    return session, json.loads(meta["raspv_patient"])


OTHER_REPRESENTATION_HINT = ("run it anyway with --other-representation (the records then say "
                             "\"other_representation\": true), or train one on this representation")


def representation(spv_params: dict) -> dict:
    """What a patient sees with these spv node parameters (the node's defaults for the rest):
    the mode, the device's phosphene count, field of view [deg], grid and field shape."""
    from raspv_bringup.registry import schema_for
    from raspv_spv.spv_node_rebuild import checked_config

    config, _ = checked_config({**schema_for("spv").defaults(), **spv_params})
    d = config.device
    return {"mode": config.mode, "phosphenes": int(d.num_phosphenes), "fov_deg": round(float(d.fov_deg), 3),
            "grid": d.grid, "field": d.field}


def describe_representation(rep: dict) -> str:
    return (f"{rep['mode']}, {rep['phosphenes']} phosphenes over {rep['fov_deg']:g} deg "
            f"({rep['grid']} grid, {rep['field']} field)")


def representation_mismatch(model: str | Path, spv_params: dict) -> str | None:
    """One line naming both representations when the patient ``model`` ('' = shipped) was
    trained on another than ``spv_params`` show; None when they agree. Outside its training
    representation the shipped patient reached 0 of 6 goals of the example (issue 33)."""
    path = Path(model) if model else DEFAULT_MODEL
    _, meta = load_model(str(path))
    trained, shown = representation(meta.get("spv", {})), representation(spv_params)
    if trained == shown:
        return None
    return (f"learned virtual patient {path.name} was trained on {describe_representation(trained)}; "
            f"this shows {describe_representation(shown)}: refused — {OTHER_REPRESENTATION_HINT}")


def check_model(value: str) -> None:
    """File check of the subject node's ``model`` parameter ('' is the shipped model)."""
    load_model(str(Path(value) if value else DEFAULT_MODEL))


class Learned(Navigate):
    """The learned virtual patient (see the module docstring)."""

    name = "learned"

    def __init__(self, layout: PhospheneLayout, config: PolicyConfig | None = None,
                 goal: tuple[float, float] | None = None, model: str | Path = "", **kw) -> None:
        super().__init__(layout, config, goal=goal, **kw)
        self.session, self.meta = load_model(str(Path(model) if model else DEFAULT_MODEL))
        self.grid = int(self.meta.get("grid", GRID))
        self.cells = _cells(layout, self.grid)

    def features(self, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        img = np.zeros(self.grid * self.grid, np.float32)
        np.maximum.at(img, self.cells, b.astype(np.float32))
        return img.reshape(1, 1, self.grid, self.grid), goal_features(self.pose, self.goal)[None]

    def decide(self, b: np.ndarray) -> tuple[float, float]:
        image, goal = self.features(b)
        out = self.session.run(["command"], {"image": image, "goal": goal})[0][0]
        c = self.config
        return float(np.clip(out[0], -1, 1)) * c.max_linear, float(np.clip(out[1], -1, 1)) * c.max_angular
