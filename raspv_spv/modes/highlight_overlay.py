"""Object and person highlight (paper §IV-D, Figs. 14–15): phosphenes whose camera pixel falls on
the chosen classes of a segmentation go to full level, the others are dimmed by
``highlight.dim``, over any representation mode.

Inputs (optional: without them nothing is highlighted):
- ``extras["segmentation"]``: the label images, a sequence of ``(stamp [s], (h, w) class ids)``
  (the spv node keeps the last few from ``/segmentation/labels``); the one closest to the frame's
  stamp within ``highlight.max_age`` is used, so labels only meet the frame they belong to. A
  bare (h, w) array is used as is (offline use).
- ``extras["segmentation_classes"]``: the :class:`~raspv_perception.class_table.ClassTable`
  naming the ids (from ``/segmentation/classes``); ``highlight.classes`` are looked up in it
  by name or synonym (``bin`` finds ADE20K's ``ashcan``).
- ``depth`` for ``highlight.pick: nearest``.

``highlight.pick``: ``all`` classes' pixels; ``largest`` or ``nearest`` keep one instance —
a connected piece of the class mask (on the label image subsampled to at most ``PICK_WIDTH`` px
wide; pieces less than ``GAP`` px apart count as one, as a person's limbs), the largest, or the
one with the smallest median depth — so the subject is not overwhelmed (the paper highlights
one object).
"""
from __future__ import annotations

import logging
import math

import cv2
import numpy as np

from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.modes.base import Overlay
from raspv_spv.sampling import Sampling

PICK_WIDTH = 160            # px: instances are found on the label image subsampled to this width
GAP = 9                     # px at PICK_WIDTH (≈ 6 % of the image width): pieces closer than this are one instance
_log = logging.getLogger("raspv.highlight")


def closest_labels(source, stamp: float, max_age: float) -> np.ndarray | None:
    """The label image of ``source`` (sequence of (stamp, labels), or one array) for ``stamp``."""
    if source is None:
        return None
    if isinstance(source, np.ndarray):
        return source
    best = min(source, key=lambda sl: abs(sl[0] - stamp), default=None)
    if best is None or abs(best[0] - stamp) > max_age + 1e-9:
        return None
    return best[1]


class HighlightOverlay(Overlay):
    name = "highlight"
    description = "highlight the chosen segmentation classes (objects, people), dimming the rest"
    needs = frozenset({"camera"})
    optional_inputs = frozenset({"segmentation", "segmentation_classes", "depth"})
    defaults = {
        "highlight.classes": ["person"],   # class names (or synonyms) to highlight
        "highlight.pick": "all",           # all, largest or nearest instance
        "highlight.dim": 0.5,              # the other phosphenes' levels are multiplied by this
        "highlight.max_age": 0.2,          # use labels at most this far from the frame's stamp [s]
    }

    def __init__(self, settings=None) -> None:
        super().__init__(settings)
        self._ids_cache: tuple[int, tuple[str, ...], np.ndarray] | None = None
        pick = self.settings["highlight.pick"]
        if pick not in ("all", "largest", "nearest"):
            raise ValueError(f"highlight.pick must be all, largest or nearest, got {pick!r}")

    def class_lut(self, table) -> np.ndarray:
        """(65536,) bool: which class ids are highlighted (cached per class table)."""
        wanted = tuple(self.settings["highlight.classes"])
        cached = self._ids_cache
        if cached is not None and cached[0] == id(table) and cached[1] == wanted:
            return cached[2]
        ids, unknown = table.ids_for(wanted)
        if unknown:
            _log.warning("highlight: no class %s among the segmentation classes (%s); nothing is highlighted for it",
                         ", ".join(repr(u) for u in unknown), table.describe())
        lut = np.zeros(65536, bool)
        lut[ids] = True
        self._ids_cache = (id(table), wanted, lut)
        return lut

    def class_mask(self, inputs: FrameInputs) -> np.ndarray | None:
        """(h, w) bool mask of the chosen classes in the frame's label image, or None."""
        labels = closest_labels(inputs.extras.get("segmentation"), inputs.stamp, self.settings["highlight.max_age"])
        table = inputs.extras.get("segmentation_classes")
        if labels is None or table is None:
            return None
        return self.class_lut(table)[labels]

    def highlight(self, inputs: FrameInputs, sampling: Sampling) -> np.ndarray:
        labels = closest_labels(inputs.extras.get("segmentation"), inputs.stamp, self.settings["highlight.max_age"])
        table = inputs.extras.get("segmentation_classes")
        if labels is None or table is None or labels.ndim != 2:
            return np.zeros(sampling.count, bool)
        lut = self.class_lut(table)
        on_class = lut[sampling.sample(labels)] & sampling.for_shape(*labels.shape).inside
        if self.settings["highlight.pick"] == "all" or not on_class.any():
            return on_class
        region = self.instance_region(lut, labels, inputs.depth)
        at = sampling.for_shape(*region.shape)
        return on_class & region[at.rows, at.cols]

    def instance_region(self, lut: np.ndarray, labels: np.ndarray, depth: np.ndarray | None) -> np.ndarray:
        """(h', w') bool on the subsampled label image: the region of the picked instance."""
        step = max(1, math.ceil(labels.shape[1] / PICK_WIDTH))
        small = lut[labels[::step, ::step]]
        # pieces closer than GAP px (at PICK_WIDTH) are one instance: limbs and body parts often
        # show as separate pieces of a person's mask
        joined = cv2.dilate(small.astype(np.uint8), np.ones((GAP, GAP), np.uint8))
        count, region = cv2.connectedComponents(joined, connectivity=8)
        if count <= 2:
            return region > 0
        member = np.where(small, region, 0)
        if self.settings["highlight.pick"] == "largest" or depth is None:
            k = 1 + int(np.argmax(np.bincount(member.ravel(), minlength=count)[1:]))
        else:
            d = cv2.resize(depth, (small.shape[1], small.shape[0]), interpolation=cv2.INTER_NEAREST)
            medians = []
            for i in range(1, count):
                values = d[member == i]
                values = values[np.isfinite(values)]
                medians.append(float(np.median(values)) if values.size else np.inf)
            k = 1 + int(np.argmin(medians))
        return region == k

    def apply(self, levels: np.ndarray, inputs: FrameInputs, sampling: Sampling, num_levels: int) -> np.ndarray:
        """Highlighted → N_L−1, the rest × ``highlight.dim`` (rounded up); unchanged if nothing is."""
        mask = np.asarray(self.highlight(inputs, sampling), dtype=bool)
        if not mask.any():
            return levels
        dim = float(self.settings["highlight.dim"])
        out = np.ceil(levels.astype(np.float32) * np.float32(dim) - 1e-6).clip(0, num_levels - 1).astype(np.uint8)
        out[mask] = num_levels - 1
        return out
