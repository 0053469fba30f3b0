"""Segmentation networks behind one interface (no ROS): an (H, W, 3) uint8 RGB image in, a
class-id image of the same size out.

- :class:`PersonModel` — the shipped MediaPipe selfie-segmentation network (Apache-2.0,
  ``raspv_perception/models/``) in onnxruntime: 256×256 RGB in [0, 1] → person probability,
  resized back to the image. Classes: background (0), person (1).
- :class:`OnnxModel` — any semantic-segmentation ONNX model with a *model file* (YAML, see
  :mod:`raspv_perception.model_spec`) giving its input size, normalisation and labels.
- :class:`TorchScriptModel` — the same for a TorchScript ``.pt`` (PyTorch is optional).

Every problem with a model (unreadable file, wrong input shape, labels that do not match the
output) raises :class:`~raspv_perception.model_spec.ModelError` with one line naming the file
and what was expected.
"""
from __future__ import annotations

import os
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from raspv_common.extras import MissingExtra, require
from raspv_perception.class_table import ClassTable
from raspv_perception.model_spec import ModelError, ModelSpec, load_model_spec

MODELS_DIR = Path(__file__).resolve().parent / "models"
PERSON_MODEL = MODELS_DIR / "selfie_segmentation.onnx"


@dataclass
class Prediction:
    """``labels`` (H, W) uint8 (uint16 for > 256 classes) class ids at the image's size;
    ``probability`` (H, W) float32 of the foreground class for one-class models, else None."""

    labels: np.ndarray
    probability: np.ndarray | None = None


class SegmentationModel(ABC):
    """``classes`` names the ids; ``backend`` and ``path`` say what runs."""

    backend: str = ""
    classes: ClassTable
    path: Path

    @abstractmethod
    def predict(self, rgb: np.ndarray) -> Prediction:
        """Class ids of an (H, W, 3) uint8 RGB image."""

    def describe(self) -> str:
        return f"{self.backend} model {self.path.name} ({self.classes.describe(6)})"


def check_rgb(rgb: np.ndarray) -> np.ndarray:
    if not (isinstance(rgb, np.ndarray) and rgb.dtype == np.uint8 and rgb.ndim == 3 and rgb.shape[2] == 3):
        shape = getattr(rgb, "shape", None)
        raise ValueError(f"expected an (H, W, 3) uint8 RGB image, got {getattr(rgb, 'dtype', type(rgb).__name__)} {shape}")
    return rgb


def _labels_dtype(count: int) -> type:
    return np.uint8 if count <= 256 else np.uint16


def onnx_session(path: Path, threads: int):
    """An onnxruntime CPU session of ``path`` on ``threads`` threads (sequential), or ModelError in one
    line (also the learned mode's, raspv_spv/modes/learned.py)."""
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = max(1, int(threads))
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.log_severity_level = 3
    try:
        return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own exception types for bad files
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ModelError(f"{path}: not a model onnxruntime can load ({first[:200]})") from None


class PersonModel(SegmentationModel):
    """MediaPipe selfie segmentation (square 256×256 variant). The image is resized to the
    network input without keeping its aspect ratio (as MediaPipe does), and the probability is
    resized back bilinearly. ``threshold``: probability from which a pixel is person."""

    backend = "person"
    INPUT = 256

    def __init__(self, path: str | Path = PERSON_MODEL, threshold: float = 0.5, threads: int = 1) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise ModelError(f"{self.path}: no such model file (the person model ships with raspv_perception; "
                             "reinstall with `make install`)")
        self.session = onnx_session(self.path, threads)
        inp = self.session.get_inputs()[0]
        if list(inp.shape) != [1, self.INPUT, self.INPUT, 3]:
            raise ModelError(f"{self.path}: input shape {inp.shape}; expected [1, 256, 256, 3] (selfie segmentation)")
        self._input = inp.name
        self.threshold = float(threshold)
        self.classes = ClassTable.from_label_set("person")

    def probability(self, rgb: np.ndarray) -> np.ndarray:
        """(H, W) float32 person probability in [0, 1]."""
        rgb = check_rgb(rgb)
        small = cv2.resize(rgb, (self.INPUT, self.INPUT), interpolation=cv2.INTER_AREA)
        x = small.astype(np.float32)
        x *= np.float32(1.0 / 255.0)
        p = self.session.run(None, {self._input: x[None]})[0].reshape(self.INPUT, self.INPUT)
        return cv2.resize(p, (rgb.shape[1], rgb.shape[0]), interpolation=cv2.INTER_LINEAR)

    def predict(self, rgb: np.ndarray) -> Prediction:
        p = self.probability(rgb)
        return Prediction((p >= self.threshold).astype(np.uint8), p)


class _SpecModel(SegmentationModel):
    """Shared pre- and post-processing of models described by a :class:`ModelSpec`."""

    def __init__(self, spec: ModelSpec) -> None:
        self.spec = spec
        self.path = spec.model
        self.classes = spec.classes
        self._mean = np.asarray(spec.mean, np.float32)
        self._inv_std = (1.0 / np.asarray(spec.std, np.float32)).astype(np.float32)

    def _input_tensor(self, rgb: np.ndarray) -> np.ndarray:
        s = self.spec
        img = cv2.resize(check_rgb(rgb), (s.width, s.height), interpolation=cv2.INTER_LINEAR)
        if s.channel_order == "bgr":
            img = img[:, :, ::-1]
        x = img.astype(np.float32) * np.float32(1.0 / s.scale)
        x = (x - self._mean) * self._inv_std
        if s.layout == "nchw":
            x = x.transpose(2, 0, 1)
        return np.ascontiguousarray(x[None])

    def _labels(self, out: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
        """Scores (1, C, h, w) / (1, h, w, C) or ids (1, h, w) → (H, W) class ids."""
        s, k = self.spec, len(self.classes)
        a = np.asarray(out)
        if a.ndim == 4 and a.shape[0] == 1:
            channels_last = s.layout == "nhwc" or (a.shape[1] != k and a.shape[3] == k)
            c = a.shape[3] if channels_last else a.shape[1]
            if c != k:
                raise ModelError(f"{s.source}: the model outputs {c} class scores but the labels name {k} classes "
                                 f"({self.classes.label_set}); fix 'labels' (or 'background: true' if the first "
                                 "output is an extra background class)")
            ids = a[0].argmax(axis=2 if channels_last else 0)
        elif a.ndim == 3 and a.shape[0] == 1 and np.issubdtype(a.dtype, np.integer):
            ids = a[0]
        else:
            raise ModelError(f"{s.source}: model output of shape {list(a.shape)}; expected class scores "
                             "(1, C, h, w) or (1, h, w, C), or class ids (1, h, w)")
        ids = np.clip(ids, 0, k - 1).astype(_labels_dtype(k))
        if ids.shape != shape:
            ids = cv2.resize(ids, (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST)
        return ids

    def predict(self, rgb: np.ndarray) -> Prediction:
        x = self._input_tensor(rgb)
        return Prediction(self._labels(self._run(x), rgb.shape[:2]))

    @abstractmethod
    def _run(self, x: np.ndarray) -> np.ndarray:
        """The network's first output for input ``x``."""

    def check(self) -> None:
        """Run once on a grey image: wrong input shapes or outputs fail now, with the file named."""
        try:
            self.predict(np.full((self.spec.height, self.spec.width, 3), 128, np.uint8))
        except ModelError:
            raise
        except Exception as exc:  # the runtime's own errors on a shape mismatch
            first = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else type(exc).__name__
            raise ModelError(f"{self.path}: the model does not run on a {self.spec.layout.upper()} input "
                             f"{list(self._input_tensor(np.zeros((self.spec.height, self.spec.width, 3), np.uint8)).shape)} "
                             f"({first}); check input_size and layout in {self.spec.source.name}") from None


class OnnxModel(_SpecModel):
    backend = "onnx"

    def __init__(self, spec: ModelSpec, threads: int = 1) -> None:
        super().__init__(spec)
        self.session = onnx_session(spec.model, threads)
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            raise ModelError(f"{spec.model}: the model has {len(inputs)} inputs; expected one image input")
        self._input = inputs[0].name
        shape = inputs[0].shape
        want = [1, 3, spec.height, spec.width] if spec.layout == "nchw" else [1, spec.height, spec.width, 3]
        if len(shape) != 4 or any(isinstance(d, int) and d != w for d, w in zip(shape, want)):
            raise ModelError(f"{spec.model}: input shape {shape}; {spec.source.name} expects {want} "
                             f"(input_size {spec.width}x{spec.height}, layout {spec.layout})")
        self.check()

    def _run(self, x: np.ndarray) -> np.ndarray:
        return self.session.run(None, {self._input: x})[0]


class TorchScriptModel(_SpecModel):
    backend = "torchscript"

    def __init__(self, spec: ModelSpec, threads: int = 1) -> None:
        super().__init__(spec)
        try:
            torch = require("torch", "the torchscript backend")
        except MissingExtra as exc:
            raise ModelError(str(exc)) from None
        self._torch = torch
        torch.set_num_threads(max(1, int(threads)))
        try:
            self.module = torch.jit.load(str(spec.model), map_location="cpu").eval()
        except Exception as exc:  # torch raises RuntimeError/ValueError with long messages
            first = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else type(exc).__name__
            raise ModelError(f"{spec.model}: not a TorchScript file torch.jit.load can read ({first})") from None
        self.check()

    def _run(self, x: np.ndarray) -> np.ndarray:
        torch = self._torch
        with torch.inference_mode():
            out = self.module(torch.from_numpy(x))
        if isinstance(out, dict):              # torchvision-style {"out": …}
            out = out.get("out", next(iter(out.values())))
        if isinstance(out, (tuple, list)):
            out = out[0]
        return out.numpy()


def load_model(backend: str, model: str = "", labels: str = "", threshold: float = 0.5,
               threads: int = 1) -> SegmentationModel:
    """The model of a backend (``person``, ``onnx``, ``torchscript``). ``model``: file path
    ('' for the shipped person model); ``labels``: the model file (YAML) for onnx/torchscript
    ('' → the model path with ``.yaml``). Raises :class:`ModelError` (one line)."""
    if backend == "person":
        return PersonModel(model or PERSON_MODEL, threshold, threads)
    if backend not in ("onnx", "torchscript"):
        raise ModelError(f"unknown segmentation backend {backend!r}; expected person, onnx, torchscript or sim")
    if not model:
        raise ModelError(f"the {backend} backend needs a model file (parameter 'model')")
    spec = load_model_spec(Path(os.path.expanduser(model)), Path(os.path.expanduser(labels)) if labels else None)
    return OnnxModel(spec, threads) if backend == "onnx" else TorchScriptModel(spec, threads)
