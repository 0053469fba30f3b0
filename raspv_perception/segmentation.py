"""Semantic segmentation of one frame (no ROS): a model (:mod:`raspv_perception.segmentation_models`)
and, for the person model, the depth fusion (:mod:`raspv_perception.person_fusion`).

    seg = Segmenter(load_model("person"))
    result = seg.segment(rgb, scene_labels, depth)     # scene labels and depth optional
    result.labels        # (H, W) class ids at the colour image's size; seg.classes names them

The ``segmentation`` node, ``raspv bench seg``, the figure scripts and the tests use this class.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from raspv_perception.class_table import ClassTable
from raspv_perception.person_fusion import FusionConfig, FusionResult, fuse_person
from raspv_perception.segmentation_models import PersonModel, SegmentationModel


@dataclass
class SegmentationResult:
    """``labels`` (H, W) uint8/uint16 class ids; ``probability`` (H, W) float32 of the person
    model (None for other models); ``fusion`` what the depth fusion did (person model only);
    ``timings`` [ms] of ``model`` and ``fusion``."""

    labels: np.ndarray
    probability: np.ndarray | None = None
    fusion: FusionResult | None = None
    timings: dict[str, float] = field(default_factory=dict)


class Segmenter:
    """One model and, for the person model, the fusion settings (``fusion.threshold`` is the
    person probability threshold). ``fusion=None`` turns depth fusion off (the small-piece
    filter still applies to the person model)."""

    def __init__(self, model: SegmentationModel, fusion: FusionConfig | None = FusionConfig()) -> None:
        self.model = model
        self.use_depth = fusion is not None
        self.fusion = fusion or FusionConfig(threshold=getattr(model, "threshold", 0.5))

    @property
    def classes(self) -> ClassTable:
        return self.model.classes

    @property
    def is_person(self) -> bool:
        return isinstance(self.model, PersonModel)

    def segment(self, rgb: np.ndarray, scene_labels: np.ndarray | None = None,
                depth: np.ndarray | None = None) -> SegmentationResult:
        """Class ids of an (H, W, 3) uint8 RGB frame; ``scene_labels`` (h, w) uint8 and ``depth``
        (h, w) float m of the same moment make person masks whole (ignored by other models)."""
        t0 = time.perf_counter()
        if not self.is_person:
            pred = self.model.predict(rgb)
            return SegmentationResult(pred.labels, timings={"model": 1e3 * (time.perf_counter() - t0)})
        prob = self.model.probability(rgb)
        t1 = time.perf_counter()
        if not self.use_depth:
            scene_labels = depth = None
        fused = fuse_person(prob, scene_labels, depth, self.fusion)
        t2 = time.perf_counter()
        return SegmentationResult(fused.mask.astype(np.uint8), prob, fused,
                                  {"model": 1e3 * (t1 - t0), "fusion": 1e3 * (t2 - t1)})
