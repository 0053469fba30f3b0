"""ONNX export of a trained encoder, with the metadata the live ``learned`` mode reads.

Input ``inputs`` (1, C, h, w) with h and w free (any camera), output ``stimulation``
(1, 1, h, w); metadata ``raspv_channels`` (JSON), ``raspv_focal_px``, ``raspv_device``,
``raspv_num_levels``, ``raspv_config_key``. The export is checked: onnxruntime must give the
torch network's output on a real input to 1e-5.
"""
from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import numpy as np
import torch

from raspv_learn.config import LearnConfig
from raspv_learn.networks import Encoder

EXPORT_TOLERANCE = 1e-5


def export_encoder(encoder: Encoder, config: LearnConfig, num_levels: int, path: str | Path,
                   example: np.ndarray) -> float:
    """Write ``encoder`` to ``path`` (atomically); ``example`` (C, h, w) is an input it is
    checked on. Returns the largest difference between onnxruntime and torch."""
    import onnx

    from raspv_spv.modes.learned import EncoderModel

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.onnx")
    encoder = encoder.eval()
    x = torch.from_numpy(np.asarray(example, np.float32))[None]
    with warnings.catch_warnings():           # the TorchScript exporter (no onnxscript needed) says it is legacy
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.onnx.export(encoder, (x,), str(tmp), dynamo=False, opset_version=17, input_names=["inputs"],
                          output_names=["stimulation"],
                          dynamic_axes={"inputs": {2: "height", 3: "width"}, "stimulation": {2: "height", 3: "width"}})
    model = onnx.load(str(tmp))
    meta = {"raspv_channels": json.dumps(list(config.encoder.channels)), "raspv_focal_px": repr(config.encoder.focal_px),
            "raspv_device": config.device, "raspv_num_levels": str(num_levels), "raspv_config_key": config.key()}
    for k, v in meta.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = k, v
    onnx.save(model, str(tmp))
    loaded = EncoderModel(tmp)
    with torch.no_grad():
        ours = encoder(x).numpy()
    theirs = loaded.session.run(None, {"inputs": x.numpy()})[0]
    return keep_if_it_matches(tmp, path, ours, theirs)


def keep_if_it_matches(tmp: Path, path: Path, ours: np.ndarray, theirs: np.ndarray) -> float:
    """Move the exported model ``tmp`` to ``path`` when onnxruntime's output ``theirs`` is torch's
    ``ours`` to :data:`EXPORT_TOLERANCE`; otherwise delete it and raise RuntimeError. Returns the
    largest difference."""
    diff = float(np.abs(ours - theirs).max())
    if diff > EXPORT_TOLERANCE:
        tmp.unlink(missing_ok=True)
        raise RuntimeError(f"ONNX export differs from torch by {diff:.2e} (> {EXPORT_TOLERANCE})")
    os.replace(tmp, path)
    return diff
