"""What a representation mode may look at for one camera frame (no ROS).

Every field is optional: a mode declares the inputs it needs by name (see
:data:`INPUT_NAMES`, plus any key of ``extras``) and the simulator refuses to run it without
them. Images are registered to one camera: ``color`` (H, W, 3) uint8 RGB and ``depth``
(H, W) float32 metres with NaN where there is no reading; ``camera`` is their pinhole model.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

import numpy as np

from raspv_common.intrinsics import CameraIntrinsics

INPUT_NAMES = ("color", "depth", "camera", "camera_pose", "scene", "scene_labels")


@dataclass
class FrameInputs:
    """One frame's inputs.

    ``stamp``: capture time [s]. ``camera_pose``: 4×4 world ← camera optical (metres), or None.
    ``scene``: the scene-perception core's result for this frame (floor, planes, obstacles), or
    None. ``scene_labels``: (H, W) uint8 per-pixel scene class, registered to ``depth`` (any
    size: modes sample it at their rays). ``scene_stamp``: capture time [s] of the depth frame
    the scene result was computed from; earlier than ``stamp`` when an earlier result was
    carried into this frame (:mod:`raspv_perception.scene_carry`), 0 without scene.
    ``extras``: further inputs by name (stairs, navigation path, segmentation, …).
    ``cache``: what modes derived from this frame (see :meth:`cached`).
    """

    color: np.ndarray | None = None
    depth: np.ndarray | None = None
    camera: CameraIntrinsics | None = None
    stamp: float = 0.0
    camera_pose: np.ndarray | None = None
    scene: Any = None
    scene_labels: np.ndarray | None = None
    scene_stamp: float = 0.0
    extras: dict[str, Any] = field(default_factory=dict)
    cache: dict[Any, Any] = field(default_factory=dict, repr=False, compare=False)

    def cached(self, key: Any, compute: Callable[[], Any]) -> Any:
        """``compute()`` once per frame: a mode's per-frame work (an edge image, projected path
        points) that does not depend on where the phosphenes look. The display samples one
        frame at every display tick with turned rays (:mod:`raspv_spv.reprojection`), so modes
        keep the per-tick part to sampling. ``key`` must name everything the result depends
        on beyond this frame (the mode and its settings)."""
        try:
            return self.cache[key]
        except KeyError:
            value = self.cache[key] = compute()
            return value

    def has(self, name: str) -> bool:
        """True when input ``name`` is present."""
        if name in INPUT_NAMES:
            return getattr(self, name) is not None
        return self.extras.get(name) is not None

    def missing(self, names: Iterable[str]) -> list[str]:
        """The inputs among ``names`` that this frame lacks."""
        return [n for n in names if not self.has(n)]


def check_inputs(inputs: FrameInputs) -> list[str]:
    """Problems with the arrays of ``inputs`` (wrong shape or type), as messages; empty if fine."""
    problems = []
    images = {}
    c, d = inputs.color, inputs.depth
    if c is not None:
        if isinstance(c, np.ndarray) and c.dtype == np.uint8 and c.ndim == 3 and c.shape[2] == 3:
            images["color"] = c
        else:
            problems.append(f"color must be an (H, W, 3) uint8 RGB array, got {_describe(c)}")
    if d is not None:
        if isinstance(d, np.ndarray) and d.ndim == 2 and np.issubdtype(d.dtype, np.floating):
            images["depth"] = d
        else:
            problems.append(f"depth must be an (H, W) float array in metres, got {_describe(d)}")
    labels = inputs.scene_labels
    if labels is not None and (not isinstance(labels, np.ndarray) or labels.ndim != 2):
        problems.append(f"scene_labels must be an (H, W) array, got {_describe(labels)}")
    pose = inputs.camera_pose
    if pose is not None and np.shape(pose) != (4, 4):
        problems.append(f"camera_pose must be a 4x4 matrix, got shape {np.shape(pose)}")
    cam = inputs.camera
    if cam is not None and not isinstance(cam, CameraIntrinsics):
        problems.append(f"camera must be a CameraIntrinsics, got {type(cam).__name__}")
        cam = None
    for name, img in images.items():
        h, w = img.shape[:2]
        if cam is not None and abs(w / h - cam.width / cam.height) > 0.02:
            problems.append(f"{name} is {w}x{h} but the camera model is {cam.width}x{cam.height} (another aspect ratio)")
    return problems


def _describe(a: Any) -> str:
    if isinstance(a, np.ndarray):
        return f"{a.dtype} array of shape {a.shape}"
    return type(a).__name__
