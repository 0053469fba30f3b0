"""The plug-in interface of representation modes and overlays (no ROS).

A **mode** gets one frame's :class:`~raspv_spv.frame_inputs.FrameInputs` and the phosphenes'
:class:`~raspv_spv.sampling.Sampling` (centres P_i, camera pixels, rays, K_P) and returns an
integer level per phosphene, 0 … N_L−1 (0 = off). An **overlay** takes those levels and
returns new ones: the phosphenes it highlights go to full level, the others are dimmed by ×0.5
(rounded up, so a dim phosphene stays visible) — only while something is highlighted.

Both declare ``needs``: the names of the inputs they read (``color``, ``depth``, ``camera``,
``camera_pose``, ``scene``, ``scene_labels`` or a key of ``FrameInputs.extras``). The simulator
does not call them without those; the node subscribes and warns accordingly. Inputs they use
when present but can do without go in ``optional_inputs`` (the node subscribes to them too).
``defaults`` lists the settings a mode reads (e.g. ``max_depth``) with their default values;
the simulator passes the configured values (the spv node's parameters) over them.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar, Mapping

import numpy as np

from raspv_spv.frame_inputs import FrameInputs
from raspv_spv.sampling import Sampling


def quantise(fraction: np.ndarray, num_levels: int) -> np.ndarray:
    """Levels ⌈fraction·(N_L−1)⌉ (the authors' rule) as uint8, fraction clipped to [0, 1];
    NaN gives 0. A tolerance of 1e-9 keeps exact multiples from rounding up."""
    levels = np.ceil(np.asarray(fraction, dtype=np.float64) * (num_levels - 1) - 1e-9)
    # fmax/fmin send NaN to 0 and are ~10× cheaper than nan_to_num + clip (run every display tick)
    return np.fmin(np.fmax(levels, 0.0), num_levels - 1).astype(np.uint8)


class _Plugin(ABC):
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    needs: ClassVar[frozenset[str]] = frozenset()
    optional_inputs: ClassVar[frozenset[str]] = frozenset()
    defaults: ClassVar[dict[str, Any]] = {}

    def __init__(self, settings: Mapping[str, Any] | None = None) -> None:
        self.settings: dict[str, Any] = {**self.defaults, **dict(settings or {})}


class Mode(_Plugin):
    """Levels per phosphene from a frame."""

    @abstractmethod
    def levels(self, inputs: FrameInputs, sampling: Sampling, num_levels: int) -> np.ndarray:
        """(N,) integer levels in [0, num_levels − 1], 0 for phosphenes outside the camera."""


class Overlay(_Plugin):
    """Highlights some phosphenes over any mode."""

    @abstractmethod
    def highlight(self, inputs: FrameInputs, sampling: Sampling) -> np.ndarray:
        """(N,) bool: the phosphenes to show at full level."""

    def apply(self, levels: np.ndarray, inputs: FrameInputs, sampling: Sampling, num_levels: int) -> np.ndarray:
        """Highlighted → N_L−1, the rest ×0.5 (rounded up); unchanged if nothing is highlighted."""
        mask = np.asarray(self.highlight(inputs, sampling), dtype=bool)
        if mask.shape != levels.shape:
            raise ValueError(f"overlay {self.name} highlighted {mask.shape} phosphenes, expected {levels.shape}")
        if not mask.any():
            return levels
        out = (levels.astype(np.uint16) + 1) // 2
        out[mask] = num_levels - 1
        return out.astype(np.uint8)
