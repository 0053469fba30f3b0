"""Learned: an encoder trained end to end through the differentiable twin of this simulator.

``raspv learn train`` (package ``raspv_learn``, docs/learn.md) trains a small convolutional
network that turns what the camera sees into a stimulation map, through the twin of the
renderer, against a decoder that must recover the floor/wall/obstacle map from the phosphene
images; the network is exported to ONNX and this mode runs it with onnxruntime (one thread):

1. once per camera frame (:meth:`FrameInputs.cached`), :func:`encoder_inputs` resamples the
   frame to the encoder's angular resolution (focal length ``input_focal_px``, independent of
   the camera's size and field of view): grey, nearness min(1, 0.5 m / depth), depth present,
   and the fractions of the scene classes (``/scene/labels``: floor, wall, horizontal,
   obstacle, other, blocked floor) — 9 channels; the network gives a stimulation map s ∈ [0, 1]
   on that grid;
2. at every display tick, each phosphene takes s bilinearly at its camera pixel P_i^C
   (turned rays included) and its level is ⌊s·(N_L − 1) + ½⌋ (:func:`stimulation_levels`, the
   rule the training quantises with); rays outside the camera are off.

The model file (``learned_model``; "" is the shipped encoder for the configured ``device``
when there is one, else the one for ``optimist``) carries its input channels, focal length
and the device it was trained for as ONNX metadata (:class:`EncoderModel`).
"""
from __future__ import annotations

import json
import os
import threading
from pathlib import Path

import cv2
import numpy as np

from raspv_perception import scene_labels as L
from raspv_spv.modes.base import Mode

MODELS_DIR = Path(__file__).resolve().parents[2] / "raspv_learn" / "models"
FALLBACK_DEVICE = "optimist"
CHANNELS = ("grey", "nearness", "depth_valid", "floor", "wall", "horizontal", "obstacle", "other", "floor_blocked")
CLASS_CHANNELS = {"floor": L.FLOOR, "wall": L.WALL, "horizontal": L.HORIZONTAL, "obstacle": L.OBSTACLE,
                  "other": L.OTHER, "floor_blocked": L.FLOOR_BLOCKED}
NEAR_M = 0.5          # nearness = min(1, NEAR_M / depth): 1 up to 0.5 m, 0.17 at 3 m, 0 without depth


class ModelError(ValueError):
    """A learned-encoder file that cannot be used."""


def stimulation_levels(stimulation: np.ndarray, num_levels: int) -> np.ndarray:
    """Levels ⌊s·(N_L − 1) + ½⌋ (uint8) of stimulation ``s`` ∈ [0, 1]; NaN → 0. Training
    quantises with the same rule (straight through), so small outputs are off."""
    s = np.asarray(stimulation, dtype=np.float64)
    levels = np.floor(s * (num_levels - 1) + 0.5)
    return np.fmin(np.fmax(levels, 0.0), num_levels - 1).astype(np.uint8)


def input_size(camera, focal_px: float) -> tuple[int, int]:
    """(width, height) of the encoder's input grid for ``camera`` at focal length ``focal_px``."""
    k = focal_px / camera.fx
    return max(8, int(round(camera.width * k))), max(8, int(round(camera.height * k)))


def _area(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``image`` (H, W) resampled to ``size`` = (w, h): an area average by the largest whole
    factor q (OpenCV's fast path), then bilinear to the exact size (both centre-aligned, so
    grid cell j still sits at camera pixel (j + ½)·W/w − ½)."""
    h0, w0 = image.shape[:2]
    w, h = size
    q = max(1, min(w0 // w, h0 // h))
    if q > 1:
        image = cv2.resize(image, (-(-w0 // q), -(-h0 // q)), interpolation=cv2.INTER_AREA)
    return cv2.resize(image, (w, h), interpolation=cv2.INTER_LINEAR)


def encoder_inputs(color: np.ndarray | None, depth: np.ndarray | None, labels: np.ndarray | None, size: tuple[int, int],
                   channels=CHANNELS) -> np.ndarray:
    """(C, h, w) float32 encoder input of one registered RGB-D frame (any resolutions of one
    camera) resampled to ``size`` = (w, h) (:func:`_area`, plane by plane: single-channel
    resampling is OpenCV's fastest); channels in the order of ``channels``."""
    out = np.empty((len(channels), size[1], size[0]), np.float32)
    d = ok = None
    for i, name in enumerate(channels):
        if name == "grey":
            plane = cv2.cvtColor(np.ascontiguousarray(color), cv2.COLOR_RGB2GRAY).astype(np.float32)
            plane *= np.float32(1.0 / 255.0)
        elif name in ("nearness", "depth_valid"):
            if ok is None:
                d = np.asarray(depth, dtype=np.float32)
                with np.errstate(invalid="ignore"):
                    ok = (d > 0) & np.isfinite(d)             # NaN compares False
            if name == "depth_valid":
                plane = ok.astype(np.float32)
            else:
                with np.errstate(divide="ignore"):
                    plane = np.minimum(np.float32(1.0), np.float32(NEAR_M) / np.where(ok, d, np.float32(np.inf)))
        elif name in CLASS_CHANNELS:
            plane = (np.asarray(labels) == CLASS_CHANNELS[name]).astype(np.float32)
        else:
            raise ModelError(f"unknown encoder input channel {name!r}; known: {', '.join(CHANNELS)}")
        out[i] = _area(plane, size)
    return out


def sample_map(stimulation: np.ndarray, uv: np.ndarray, camera_size: tuple[int, int]) -> np.ndarray:
    """Bilinear values (N,) of a map (h, w) at camera pixels ``uv`` (N, 2) of a camera of
    ``camera_size`` = (W, H): map x = (u + ½)·w/W − ½ (area-resampling centres), clamped at
    the border (``torch.nn.functional.grid_sample`` with ``align_corners=False, padding_mode=
    "border"`` computes the same)."""
    h, w = stimulation.shape
    x = (uv[:, 0] + 0.5) * (w / camera_size[0]) - 0.5
    y = (uv[:, 1] + 0.5) * (h / camera_size[1]) - 0.5
    x = np.clip(np.nan_to_num(x), 0.0, w - 1.0)
    y = np.clip(np.nan_to_num(y), 0.0, h - 1.0)
    x0 = np.minimum(np.floor(x).astype(np.intp), w - 2) if w > 1 else np.zeros(len(x), np.intp)
    y0 = np.minimum(np.floor(y).astype(np.intp), h - 2) if h > 1 else np.zeros(len(y), np.intp)
    fx, fy = x - x0, y - y0
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    top = stimulation[y0, x0] * (1 - fx) + stimulation[y0, x1] * fx
    bottom = stimulation[y1, x0] * (1 - fx) + stimulation[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


class EncoderModel:
    """An exported encoder: ONNX input ``inputs`` (1, C, h, w) → output ``stimulation``
    (1, 1, h, w) in [0, 1], with metadata ``raspv_channels`` (JSON list), ``raspv_focal_px``,
    ``raspv_device`` and ``raspv_num_levels`` (what it was trained for)."""

    def __init__(self, path: str | Path, threads: int = 1) -> None:
        from raspv_perception.model_spec import ModelError as SessionError
        from raspv_perception.segmentation_models import onnx_session

        self.path = Path(path)
        if not self.path.is_file():
            raise ModelError(f"{self.path}: no such learned-encoder file (raspv learn train writes one; see docs/learn.md)")
        try:
            self.session = onnx_session(self.path, threads)
        except SessionError as exc:
            raise ModelError(str(exc)) from None
        meta = self.session.get_modelmeta().custom_metadata_map
        try:
            self.channels = tuple(json.loads(meta["raspv_channels"]))
            self.focal_px = float(meta["raspv_focal_px"])
            self.device = meta.get("raspv_device", "")
            self.num_levels = int(meta.get("raspv_num_levels", 0))
        except (KeyError, ValueError, TypeError):
            raise ModelError(f"{self.path}: not a RASPV learned encoder (no raspv_channels/raspv_focal_px metadata; "
                             "export it with raspv learn train or raspv learn export)") from None
        unknown = [c for c in self.channels if c not in CHANNELS]
        if unknown or not self.channels or not self.focal_px > 0:
            raise ModelError(f"{self.path}: bad metadata (channels {list(self.channels)}, focal {self.focal_px})")
        inp = self.session.get_inputs()[0]
        if len(inp.shape) != 4 or inp.shape[1] != len(self.channels):
            raise ModelError(f"{self.path}: input shape {inp.shape}; expected [1, {len(self.channels)}, h, w]")
        self._input = inp.name

    @property
    def needs(self) -> frozenset[str]:
        out = {"camera"}
        if "grey" in self.channels:
            out.add("color")
        if {"nearness", "depth_valid"} & set(self.channels):
            out.add("depth")
        if set(CLASS_CHANNELS) & set(self.channels):
            out.add("scene_labels")
        return frozenset(out)

    def stimulation(self, color, depth, labels, camera) -> np.ndarray:
        """(h, w) float32 stimulation map of one frame."""
        x = encoder_inputs(color, depth, labels, input_size(camera, self.focal_px), self.channels)
        out = self.session.run(None, {self._input: x[None]})[0]
        return np.asarray(out, dtype=np.float32).reshape(x.shape[1:])


_MODELS: dict[tuple[str, float], EncoderModel] = {}
_MODELS_LOCK = threading.Lock()


def shipped_model(device: str) -> Path:
    """The shipped encoder for ``device`` (a preset name or a device YAML path), or the
    fallback device's."""
    own = MODELS_DIR / f"{Path(str(device)).stem}.onnx"
    return own if own.is_file() else MODELS_DIR / f"{FALLBACK_DEVICE}.onnx"


def load_encoder(path: str | Path) -> EncoderModel:
    """The encoder at ``path``, loaded once per file version (rebuilds of the simulator and
    fallback variants share it)."""
    p = str(Path(path).expanduser())
    try:
        key = (os.path.realpath(p), os.path.getmtime(p))
    except OSError:
        raise ModelError(f"{p}: no such learned-encoder file (raspv learn train writes one; see docs/learn.md)") from None
    with _MODELS_LOCK:
        model = _MODELS.get(key)
        if model is None:
            model = _MODELS[key] = EncoderModel(p)
        return model


def check_model(value: str) -> None:
    """File check of the spv node's ``learned_model`` parameter (``raspv launch`` runs it)."""
    load_encoder(value)


class LearnedMode(Mode):
    """Levels from the learned encoder (see the module docstring)."""

    name = "learned"
    description = "encoder learned end to end through the differentiable twin (ONNX, onnxruntime)"
    needs = frozenset({"color", "depth", "scene_labels", "camera"})
    defaults = {"learned_model": "", "device": FALLBACK_DEVICE}

    def __init__(self, settings=None) -> None:
        super().__init__(settings)
        path = self.settings["learned_model"] or shipped_model(self.settings["device"])
        self.model = load_encoder(path)
        self.needs = self.model.needs

    def levels(self, inputs, sampling, num_levels):
        camera = inputs.camera
        stimulation = inputs.cached(("learned", str(self.model.path)),
                                    lambda: self.model.stimulation(inputs.color, inputs.depth, inputs.scene_labels,
                                                                   camera))
        s = sample_map(stimulation, sampling.uv, (camera.width, camera.height))
        return np.where(sampling.inside, stimulation_levels(s, num_levels), 0).astype(np.uint8)
